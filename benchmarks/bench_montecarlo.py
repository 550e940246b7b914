"""Monte-Carlo throughput: trials per second of the paper's campaign at the geometric
fidelity with 1 and 2 worker processes (scaling efficiency), where the time of a trial
goes, and the time of one render-fidelity trial.

Run: ``.venv/bin/python benchmarks/bench_montecarlo.py [--trials N] [--no-render]``

Each configuration runs ``twin montecarlo scenarios/paper_hall.toml --no-budget`` through
:func:`twin.montecarlo.run_montecarlo` into a temporary folder. The baseline of the ratios
is the one-worker rate measured in the same run: scaling efficiency = rate(2) / (2 rate(1)).
The split of one trial comes from its ``timings_s`` (the campaign's own accounting).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from rich.console import Console
from rich.table import Table

import twin.sim  # noqa: F401  # isort: skip
from twin.montecarlo import run_montecarlo
from twin.run.runner import run_scenario
from twin.scenario import load_scenario

HALL = Path(__file__).resolve().parents[1] / "scenarios" / "paper_hall.toml"
PARTS = ("physics", "render", "detection", "planning", "solving", "other")


def _rate(scenario, trials: int, workers: int, fidelity: str = "geometric") -> float:
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        rows = run_montecarlo(
            scenario,
            tmp,
            trials,
            fidelity=fidelity,
            workers=workers,
            master_seed=1,
            strategy="paper",
        )
        wall = time.perf_counter() - t0
    assert len({r["trial"] for r in rows}) == trials
    return trials / wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=12, help="geometric trials per setting")
    parser.add_argument("--no-render", action="store_true", help="skip the render trial")
    args = parser.parse_args()
    console = Console()
    sc = load_scenario(HALL)
    console.print(f"{os.cpu_count()} CPUs; {args.trials} geometric trials per setting")

    table = Table(title="Monte-Carlo throughput, scenarios/paper_hall.toml (whole runs)")
    for col in ("fidelity", "workers", "trials", "trials/s", "trials/s/worker", "vs 1 worker"):
        table.add_column(col, justify="right")
    r1 = _rate(sc, args.trials, 1)
    r2 = _rate(sc, args.trials, 2)
    table.add_row("geometric", "1", str(args.trials), f"{r1:.2f}", f"{r1:.2f}", "1.00")
    table.add_row(
        "geometric", "2", str(args.trials), f"{r2:.2f}", f"{r2 / 2:.2f}", f"{r2 / r1:.2f}"
    )
    console.print(table)
    console.print(f"scaling efficiency with 2 workers: {r2 / (2 * r1):.2f}")

    split = Table(title="Where one trial's time goes [s] (one process, seed 1)")
    for col in ("fidelity", "wall", *PARTS):
        split.add_column(col, justify="right")
    for fidelity in ("geometric",) + (() if args.no_render else ("render",)):
        with tempfile.TemporaryDirectory() as tmp:
            res = run_scenario(sc, tmp, fidelity=fidelity, seed=1, report=False, strategy="paper")
        t = res["timings_s"]
        split.add_row(
            fidelity, f"{res['wall_time_s']:.2f}", *(f"{t.get(p, 0.0):.2f}" for p in PARTS)
        )
    console.print(split)


if __name__ == "__main__":
    main()
