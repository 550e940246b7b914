"""Train MaskablePPO on random sites and judge it on a held-out test set against greedy.

Trains sb3-contrib's ``MaskablePPO`` (``MultiInputPolicy`` on the environment's raw Dict
observation) through :func:`twin.envs.sb3.make_sb3_vec_env` on random corridors and halls
(``scenario="random"``, the vector seeded from :data:`twin.envs.heldout.TRAINING_SEEDS`),
saves the model as ``OUT/model.zip``, prints the training's steps per second, then
evaluates it exactly as ::

    twin strategies --test-set random --policy OUT/model.zip --baseline greedy

does (the command itself, on the held-out sites; its table, episodes and paired
differences in ``OUT/eval``). Needs the ``rl`` extra (``make test-rl`` installs it into
.venv-rl)::

    .venv-rl/bin/python examples/train_maskable_ppo.py --timesteps 200000 --envs 16
    .venv-rl/bin/python examples/train_maskable_ppo.py --timesteps 4000 --eval-episodes 5
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from twin.envs.heldout import DEFAULT_TEST_SET, TEST_SETS, TRAINING_SEEDS, check_training_seed


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--timesteps", type=int, default=200_000, help="environment steps")
    parser.add_argument(
        "--scenario",
        default="random",
        help="the training site: 'random' (a random site per episode) or a scenario",
    )
    parser.add_argument("--envs", type=int, default=16, help="episodes side by side")
    parser.add_argument(
        "--planner",
        choices=("stands", "campaign"),
        default="stands",
        help="how training plays the moves (the site's table: fast)",
    )
    parser.add_argument(
        "--eval-planner",
        choices=("stands", "campaign"),
        default="campaign",
        help="how the evaluation plays them (the campaign itself, closed-loop)",
    )
    parser.add_argument("--test-set", choices=tuple(TEST_SETS), default=DEFAULT_TEST_SET)
    parser.add_argument(
        "--eval-episodes", type=int, help="the test set's first N episodes (default: all)"
    )
    parser.add_argument("--baseline", default="greedy")
    parser.add_argument(
        "--seed",
        type=int,
        default=TRAINING_SEEDS.start,
        help=f"training seed, in {TRAINING_SEEDS.start} .. {TRAINING_SEEDS.stop - 1}",
    )
    parser.add_argument("--n-steps", type=int, default=256, help="PPO's rollout per episode")
    parser.add_argument("--out", type=Path, default=Path("out/maskable_ppo"))
    args = parser.parse_args()
    try:
        check_training_seed(args.seed, args.envs)
    except ValueError as exc:
        parser.error(str(exc))

    import torch
    from sb3_contrib import MaskablePPO

    from twin.cli import main as twin
    from twin.envs.sb3 import make_sb3_vec_env

    torch.set_num_threads(1)  # the environment is the cost; one core for the network
    args.out.mkdir(parents=True, exist_ok=True)
    venv = make_sb3_vec_env(args.envs, scenario=args.scenario, planner=args.planner)
    venv.seed(args.seed)
    model = MaskablePPO(
        "MultiInputPolicy",
        venv,
        n_steps=args.n_steps,
        batch_size=256,
        n_epochs=4,
        gamma=0.995,
        seed=args.seed,
        device="cpu",
        verbose=1,  # a table of the rollouts' returns and the losses per update
    )
    start = time.perf_counter()
    model.learn(total_timesteps=args.timesteps)
    wall = time.perf_counter() - start
    steps = model.num_timesteps
    print(
        f"trained {steps} steps in {wall:.0f} s: {steps / wall:.1f} steps/s "
        f"({args.envs} episodes side by side, {args.scenario} sites, planner {args.planner})"
    )
    path = args.out / "model.zip"
    model.save(path)
    venv.close()
    print(f"model: {path}")

    argv = ["strategies", "--test-set", args.test_set, "--policy", str(path)]
    argv += ["--baseline", args.baseline, "--planner", args.eval_planner]
    if args.eval_episodes:
        argv += ["--episodes", str(args.eval_episodes)]
    argv += ["--out", str(args.out / "eval"), "--overwrite"]
    print("twin " + " ".join(argv))
    return twin(argv)


if __name__ == "__main__":
    raise SystemExit(main())
