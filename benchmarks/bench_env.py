"""The Gymnasium environment's speed: decisions (steps) per second on the paper's hall.

Run: ``.venv/bin/python benchmarks/bench_env.py [--seconds S] [--planner NAME...]``

For vector sizes 1, 8, 64 (and 256 with the site's table) in one process, as the
environment's own vector (``batched``: ``gymnasium.make_vec``'s default, the episodes of a
site are the rows of one batch) and as Gymnasium's ``SyncVectorEnv``, and for 2
asynchronous workers (``AsyncVectorEnv``):

- ``random``: random masked moves (the issue's measure);
- ``paper``: the paper's policy, whose moves repeat from episode to episode.

Each for the environment's planners (``--planner``, default both): ``campaign`` (the
campaign itself: random play reaches new decisions all the time, and the campaign runs
every one of them) and ``stands`` (a table of the site, :mod:`twin.envs.stands`, which
finds each leg the first time it is asked for and reads it back after).

Each configuration plays windows of S seconds of wall time (default 15) from fresh
environments and a fresh table: ``cold`` is the first (the table fills); ``warm`` is
measured once the table has filled (it grew by less than 1 % over a window; with the
campaign planner, after one window), and ``from`` says when it began. In other processes
(``sync`` with its workers' tables, ``async``) the table is not seen: one unmeasured window.
The ratio is the warm rate against one environment with the same policy and
planner, measured in the same run; the absolute figures (steps/s on one core, the target
being 1000 with random moves) are printed with the machine's load average. Resets are
counted in the time, not as steps.

Then ``agreement`` (``--episodes N``, default 300): for each planner, N episodes of the
paper's policy played step by step in the environment against ``twin montecarlo --fidelity
batch --strategy paper`` with N trials: per visit the RMS camera position error and their
ratio (the issue asks for 15 %).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import gymnasium
import numpy as np
from rich.console import Console
from rich.table import Table

import twin.sim  # noqa: F401  (headless rendering)
from twin.envs import ENV_ID, CpsCampaignEnv
from twin.envs.comparison import play_episode
from twin.envs.plan_memo import clear_memos
from twin.envs.policies import policy_named
from twin.envs.stand_site import _SITES, clear_sites
from twin.montecarlo import run_montecarlo
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
HALL = ROOT / "scenarios" / "paper_hall.toml"


def _make() -> CpsCampaignEnv:
    return CpsCampaignEnv(HALL)


def _make_stands() -> CpsCampaignEnv:
    return CpsCampaignEnv(HALL, planner="stands")


def load() -> str:
    one, five, fifteen = os.getloadavg()
    return f"{one:.2f} {five:.2f} {fifteen:.2f}"


def _table_size() -> int:
    """Legs the process's site tables hold."""
    return sum(len(site.legs) for site in _SITES.values())


def measure(
    mode: str, n: int, policy: str, seconds: float, planner: str = "campaign"
) -> tuple[float, float, float, int]:
    """(cold steps/s, warm steps/s, when the warm window started (s), steps in those
    windows) of ``n`` fresh environments of ``mode`` playing ``policy`` (see the
    module)."""
    clear_memos()
    clear_sites()
    if mode == "batched":
        envs = gymnasium.make_vec(ENV_ID, num_envs=n, scenario=str(HALL), planner=planner).unwrapped
    else:
        cls = gymnasium.vector.SyncVectorEnv if mode == "sync" else gymnasium.vector.AsyncVectorEnv
        envs = cls([_make_stands if planner == "stands" else _make] * n)
    rng = np.random.default_rng(0)
    try:
        _, info = envs.reset(seed=list(range(n)))
        actors = None
        if policy == "paper":
            singles = [e.unwrapped for e in envs.envs]  # type: ignore[attr-defined]
            actors = [policy_named("paper")(e, k) for k, e in enumerate(singles)]
        restarting = np.zeros(n, dtype=bool)
        rates, total = [], 0
        window, played, grown = 0, 0.0, 1.0
        while True:
            # Window 0 is cold; then unmeasured windows until the table has filled (it
            # grew by less than 1 % over the last one, at most 10 of them), then warm.
            warming = window > 0 and not rates[1:] and grown > 0.01 and window <= 10
            before = _table_size()
            steps = 0
            start = time.perf_counter()
            while time.perf_counter() - start < seconds:
                actions = np.zeros(n, dtype=np.int64)
                for k in range(n):
                    mask = info["action_mask"][k]
                    if restarting[k] or not mask.any():
                        continue  # this step resets it
                    if actors is None:
                        actions[k] = rng.choice(np.flatnonzero(mask))
                    else:
                        one = {"decision": info["decision"][k], "action_mask": mask}
                        actions[k] = actors[k]({}, one)
                _obs, _, terminated, truncated, info = envs.step(actions)
                steps += int((~restarting).sum())
                if actors is not None:
                    for k in np.flatnonzero(restarting):
                        actors[k] = policy_named("paper")(singles[k], k)
                restarting = terminated | truncated
            played += time.perf_counter() - start
            if window == 0 or not warming:
                rates.append(steps / (time.perf_counter() - start))
                total += steps
            if len(rates) == 2:
                return rates[0], rates[1], played - seconds, total
            grown = (_table_size() - before) / max(before, 1)
            if planner != "stands" or mode == "async":
                grown = 1.0 if window == 0 else 0.0  # no table seen: one unmeasured window
            window += 1
    finally:
        envs.close()


def agreement(episodes: int, console: Console, planner: str = "campaign") -> None:
    """The paper's policy in the environment against ``twin montecarlo --fidelity batch``."""
    env = CpsCampaignEnv(HALL, planner=planner)
    ours: dict[tuple[str, int], list[float]] = {}
    start = time.perf_counter()
    steps = 0
    for seed in range(episodes):
        steps += play_episode(env, "paper", seed)[0]
        assert env.batch is not None
        for visit, outcome in env.batch.visits.items():
            ours.setdefault(visit, []).append(1e3 * float(outcome.position_error[0]))
    played = time.perf_counter() - start
    env.close()
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        rows = run_montecarlo(
            load_scenario(HALL), tmp, episodes, fidelity="batch", strategy="paper"
        )
        batch = time.perf_counter() - start
    theirs: dict[tuple[str, int], list[float]] = {}
    for row in rows:
        if row["config"] == "all":
            theirs.setdefault((row["camera"], row["visit"]), []).append(row["position_error_mm"])
    table = Table(
        title=f"the paper's policy ({planner}), {episodes} episodes, against twin montecarlo"
    )
    for name in ("visit", "environment RMS mm", "montecarlo RMS mm", "ratio"):
        table.add_column(name, justify="right")
    for visit, values in ours.items():
        a = float(np.sqrt(np.nanmean(np.square(values))))
        b = float(np.sqrt(np.nanmean(np.square(theirs.get(visit, [np.nan])))))
        table.add_row(f"{visit[0]} #{visit[1]}", f"{a:.1f}", f"{b:.1f}", f"{a / b:.3f}")
    console.print(table)
    console.print(
        f"environment: {episodes} episodes, {steps} steps in {played:.1f} s "
        f"({steps / played:.0f} steps/s); montecarlo: {batch:.1f} s; load {load()}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=15.0)
    parser.add_argument("--episodes", type=int, default=300)
    parser.add_argument("--planner", nargs="+", default=["campaign", "stands"])
    args = parser.parse_args()
    console = Console(width=120)
    table = Table(title=f"camnet/CpsCampaign-v0 on the paper's hall ({args.seconds:g} s each)")
    columns = (
        "planner", "vector", "envs", "policy", "steps", "cold /s", "warm /s", "from s",
        "x one env",
    )  # fmt: skip
    for name in (*columns, "load"):
        table.add_column(name, justify="right")
    base: dict[tuple[str, str], float] = {}  # one environment of the environment's own vector
    for planner in args.planner:
        for policy in ("paper", "random"):
            for mode, n in (
                ("batched", 1),
                ("batched", 8),
                ("batched", 64),
                ("batched", 256),
                ("sync", 8),
                ("sync", 64),
                ("async", 2),
            ):
                if policy == "paper" and mode == "async":
                    continue  # the policy reads the environment: it runs in the same process
                if n == 256 and planner != "stands":
                    continue  # a step a second or so: the campaign runs every decision
                cold, warm, since, steps = measure(mode, n, policy, args.seconds, planner)
                base.setdefault((planner, policy), warm)
                ratio = warm / base[(planner, policy)]
                table.add_row(planner, mode, str(n), policy, str(steps), f"{cold:.1f}",
                              f"{warm:.1f}", f"{since:.0f}", f"{ratio:.2f}", load())  # fmt: skip
                console.print(f"{planner} {mode} {n} {policy}: {cold:.1f} / {warm:.1f} steps/s")
    console.print(table)
    console.print("target: 1000 steps/s with random moves on one core")
    if args.episodes > 0:  # --episodes 0: the speed table only
        for planner in args.planner:
            agreement(args.episodes, console, planner)


if __name__ == "__main__":
    main()
