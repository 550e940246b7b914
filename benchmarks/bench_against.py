"""Time per geometric trial of the paper's hall, this tree against an earlier commit,
measured in the same run.

The earlier commit is checked out in a temporary git worktree; batches of trials run in
subprocesses, one tree's then the other's, in turn, so that both see the same machine.
Each batch reports the CPU time of every trial after its first (the first pays for
imports and caches) and a digest of its results, so the table also says whether both
trees computed the same calibrations for the same seeds. Both trees run the same seeds, so
the comparison is paired: the ratio of the two times of each seed, its median and a
bootstrap 95 % interval of that median.

    .venv/bin/python benchmarks/bench_against.py [--ref COMMIT] [--rounds 3] [--trials 4]

The default reference is the commit before the campaign's redesign (its decisions as a
strategy): the redesign must not make a trial slower.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

ROOT = Path(__file__).resolve().parents[1]
REDESIGN_BASE = "93cf2a8"
"""The last commit before the campaign's decisions became a strategy."""

BATCH = r"""
import hashlib, json, sys, tempfile, time
import twin.sim  # noqa: F401
import twin
from twin.run.runner import run_scenario
seeds = [int(s) for s in sys.argv[2:]]
times, digest = [], hashlib.sha256()
for seed in seeds:
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.process_time()
        res = run_scenario(sys.argv[1], tmp, fidelity="geometric", seed=seed, report=False)
        times.append(time.process_time() - t0)
    keep = [(c["camera"], c["visit"], c["parameters"]) for c in res["calibrations"]]
    digest.update(json.dumps(keep, sort_keys=True).encode())
print(json.dumps({"times": times[1:], "digest": digest.hexdigest()[:12], "twin": twin.__file__}))
"""


def _batch(tree: Path, seeds: list[int]) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree), "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    scenario = tree / "scenarios" / "paper_hall.toml"
    out = subprocess.run(
        [sys.executable, "-c", BATCH, str(scenario), *map(str, seeds)],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    if out.returncode != 0:
        raise RuntimeError(f"trials in {tree} failed:\n{out.stderr[-3000:]}")
    result = json.loads(out.stdout.strip().splitlines()[-1])
    if not result["twin"].startswith(str(tree)):
        raise RuntimeError(f"the batch imported twin from {result['twin']}, not from {tree}")
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ref", default=REDESIGN_BASE, help="the commit to compare against")
    parser.add_argument("--rounds", type=int, default=3, help="batches per tree")
    parser.add_argument("--trials", type=int, default=4, help="timed trials per batch")
    args = parser.parse_args()
    console = Console()
    with tempfile.TemporaryDirectory(prefix="bench-ref-") as tmp:
        ref = Path(tmp) / "tree"
        subprocess.run(
            ["git", "-C", str(ROOT), "worktree", "add", "--detach", str(ref), args.ref],
            check=True,
            capture_output=True,
        )
        try:
            trees = {"this tree": ROOT, f"ref {args.ref}": ref}
            times: dict[str, list[float]] = {name: [] for name in trees}
            digests: dict[str, set[str]] = {name: set() for name in trees}
            load = os.getloadavg()
            for k in range(args.rounds):
                # The same seeds for both trees in a round; a warm-up seed first.
                seeds = [1000 + k * (args.trials + 1) + i for i in range(args.trials + 1)]
                for name, tree in trees.items():
                    batch = _batch(tree, seeds)
                    times[name] += batch["times"]
                    digests[name].add(f"{k}:{batch['digest']}")
                    console.print(f"round {k + 1}: {name}: {batch['times']}")
        finally:
            subprocess.run(
                ["git", "-C", str(ROOT), "worktree", "remove", "--force", str(ref)],
                check=False,
                capture_output=True,
            )
    table = Table(title="Geometric trial of scenarios/paper_hall.toml: CPU time per trial [s]")
    for col in ("tree", "trials", "median", "quartiles"):
        table.add_column(col, justify="right")
    ref_name = f"ref {args.ref}"
    for name, values in times.items():
        q = statistics.quantiles(values, n=4)
        median = statistics.median(values)
        table.add_row(name, str(len(values)), f"{median:.3f}", f"{q[0]:.3f}-{q[2]:.3f}")
    console.print(table)
    ratios = np.array(times["this tree"]) / np.array(times[ref_name])
    rng = np.random.default_rng(0)
    boot = np.median(rng.choice(ratios, (10_000, len(ratios))), axis=1)
    low, high = np.percentile(boot, [2.5, 97.5])
    console.print(
        f"this tree / ref, seed by seed: median {np.median(ratios):.3f} "
        f"(95 % bootstrap interval {low:.3f}-{high:.3f}, {len(ratios)} seeds)"
    )
    same = digests["this tree"] == digests[ref_name]
    console.print(f"same calibrations for the same seeds: {'yes' if same else 'NO'}")
    console.print(f"load average before the run: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} ")
    console.print(f"on {os.cpu_count()} CPUs")


if __name__ == "__main__":
    main()
