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

``--fresh``: the speed a user meets, each figure in a process of its own on one core
(``taskset -c 0``, BLAS threads 1): random masked play in the first S seconds after the
first reset returns, on the hall and on random sites, with the ``stands`` planner and a
cache folder of the site tables (:mod:`twin.envs.stand_cache`) that is empty (``cold``) or
was filled by an earlier process (``cached``: one that played for ``--fill`` seconds); the
same processes with the code of ``--against`` (a checkout, to give a ratio measured under
the same load).

Then ``agreement`` (``--episodes N``, default 300): for each planner, N episodes of the
paper's policy played step by step in the environment against ``twin montecarlo --fidelity
batch --strategy paper`` with N trials: per visit the RMS camera position error and their
ratio (the issue asks for 15 %).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
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
    return CpsCampaignEnv(HALL, planner="campaign")


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


def first_seconds(n: int, scenario: str, planner: str, seconds: float) -> dict[str, float]:
    """Random masked play of ``n`` environments (one environment alone, or the batched
    vector) in the first ``seconds`` after the first reset returns: env-steps (a vector
    step of n counts n), and how long the reset took, s."""
    rng = np.random.default_rng(0)
    start = time.perf_counter()
    if n == 1:
        env = CpsCampaignEnv(scenario, planner=planner)
        _, info = env.reset(seed=0)
        reset = time.perf_counter() - start
        steps, start = 0, time.perf_counter()
        while time.perf_counter() - start < seconds:
            _, _, terminated, truncated, info = env.step(
                int(rng.choice(np.flatnonzero(info["action_mask"])))
            )
            steps += 1
            if terminated or truncated:
                _, info = env.reset()
        env.close()
    else:
        envs = gymnasium.make_vec(ENV_ID, num_envs=n, scenario=scenario, planner=planner).unwrapped
        _, info = envs.reset(seed=list(range(n)))
        reset = time.perf_counter() - start
        restarting = np.zeros(n, dtype=bool)
        steps, start = 0, time.perf_counter()
        while time.perf_counter() - start < seconds:
            actions = np.zeros(n, dtype=np.int64)
            for k in range(n):
                mask = info["action_mask"][k]
                if not restarting[k] and mask.any():
                    actions[k] = rng.choice(np.flatnonzero(mask))
            _, _, terminated, truncated, info = envs.step(actions)
            steps += int((~restarting).sum())
            restarting = terminated | truncated
        envs.close()
    elapsed = time.perf_counter() - start
    return {"steps": steps, "seconds": elapsed, "rate": steps / elapsed, "reset": reset}


def _child(code: Path, cache: Path, n: int, scenario: str, planner: str, seconds: float):
    """:func:`first_seconds` in a fresh process on core 0 with ``code``'s package."""
    env = {
        **os.environ,
        "PYTHONPATH": str(code),
        "TWIN_CACHE_DIR": str(cache),
        "OMP_NUM_THREADS": "1",
        "OPENBLAS_NUM_THREADS": "1",
        "MKL_NUM_THREADS": "1",
        "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"),
    }
    argv = [sys.executable, __file__, "--child", str(n), scenario, planner, str(seconds)]
    out = subprocess.run(
        ["taskset", "-c", "0", *argv], env=env, capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def fresh(seconds: float, fill: float, against: Path | None, console: Console) -> None:
    """The ``--fresh`` table (see the module)."""
    table = Table(title=f"random masked play, the first {seconds:g} s of a fresh process")
    for name in ("code", "site", "cache", "envs", "reset s", "steps/s", "x before", "load"):
        table.add_column(name, justify="right")
    hall = str(HALL)
    with tempfile.TemporaryDirectory() as tmp:
        filled, empty = Path(tmp) / "filled", Path(tmp) / "empty"
        start = time.perf_counter()
        _child(ROOT, filled, 64, hall, "stands", fill)  # an earlier process fills the table
        console.print(f"filled the hall's table in {time.perf_counter() - start:.0f} s")
        cases = [
            ("hall", hall, "cached", 64),
            ("hall", hall, "cached", 1),
            ("hall", hall, "cold", 64),
            ("random", "random", "cold", 64),
            ("random", "random", "cold", 1),
        ]
        for site, scenario, state, n in cases:
            before = None
            if against is not None:
                old = Path(tmp) / "old"
                before = _child(against, old, n, scenario, "stands", seconds)
            cache = filled if state == "cached" else empty
            if state == "cold":
                cache = Path(tempfile.mkdtemp(dir=tmp))
            now = _child(ROOT, cache, n, scenario, "stands", seconds)
            ratio = "" if before is None else f"{now['rate'] / before['rate']:.1f}"
            if before is not None:
                table.add_row("before", site, state, str(n), f"{before['reset']:.1f}",
                              f"{before['rate']:.0f}", "", load())  # fmt: skip
            table.add_row("now", site, state, str(n), f"{now['reset']:.1f}",
                          f"{now['rate']:.0f}", ratio, load())  # fmt: skip
            console.print(f"{site} {state} {n}: {now} (before: {before})")
    console.print(table)
    console.print("targets: cached 2000 (64) and 300 (1) steps/s; cold 1000 (64)")


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
    parser.add_argument("--fresh", action="store_true", help="fresh processes only")
    parser.add_argument("--fill", type=float, default=120.0)
    parser.add_argument("--against", type=Path, help="a checkout of the code before")
    parser.add_argument("--child", nargs=4, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        n, scenario, planner, seconds = args.child
        print(json.dumps(first_seconds(int(n), scenario, planner, float(seconds))))
        return
    console = Console(width=120)
    if args.fresh:
        fresh(args.seconds, args.fill, args.against, console)
        return
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
