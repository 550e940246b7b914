"""Data stops that show all LEDs (``campaign.data_stops = "all_leds"``) against stops chosen
for accuracy (``"accuracy"``), at the batch fidelity: for each visit, the analytic
prediction of the camera's RMS position error (frame transfer and calibration, RMS over the
trials) against the batch Monte Carlo's RMS error, with the trials and LED points, and the
batch's speed both ways.

    .venv/bin/python benchmarks/bench_data_stops_batch.py [--trials 1000] [--scenario PATH]

The speed is that of ``twin montecarlo --fidelity batch`` with one worker (chunks of 200),
the plan's recording (one noise-free geometric run) timed apart.
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.table import Table

from twin.batch.steps import Point, record_plan
from twin.montecarlo import run_montecarlo
from twin.scenario import load_scenario
from twin.scenario.overrides import with_values

ROOT = Path(__file__).resolve().parents[1]
SETTINGS = ("all_leds", "accuracy")


def visit_numbers(rows: Sequence[dict[str, Any]], key: tuple[str, int]) -> dict[str, float]:
    """One visit's numbers over its calibrated trials: ``trials``, ``points`` (mean),
    ``predicted`` (RMS of the predicted error, mm), ``rms`` (Monte-Carlo RMS error, mm) and
    ``se`` (its standard error, mm, to first order from the spread of the squared errors)."""
    rs = [r for r in rows if (r["camera"], int(r["visit"])) == key and r["calibrated"]]
    e2 = np.array([r["position_error_mm"] ** 2 for r in rs])
    p2 = np.array(
        [r["predicted_transfer_rms_mm"] ** 2 + r["predicted_calibration_rms_mm"] ** 2 for r in rs]
    )
    rms = math.sqrt(e2.mean())
    return {
        "trials": len(rs),
        "points": float(np.mean([r["points"] for r in rs])),
        "predicted": math.sqrt(p2.mean()),
        "rms": rms,
        "se": rms * float(e2.std()) / (2.0 * float(e2.mean()) * math.sqrt(len(rs))),
    }


def measure(scenario, trials: int, seed: int) -> tuple[list[dict[str, Any]], float, float, int]:
    """The batch Monte Carlo's rows, its wall time, s, the plan's recording time, s, and the
    plan's data stops."""
    t0 = time.perf_counter()
    plan = record_plan(scenario)
    plan_s = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        rows = run_montecarlo(scenario, tmp, trials, fidelity="batch", master_seed=seed)
        wall = time.perf_counter() - t0
    return rows, wall, plan_s, plan.count(Point)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--scenario", default=str(ROOT / "scenarios" / "paper_hall.toml"))
    args = parser.parse_args()
    base = load_scenario(args.scenario)
    console = Console(width=140)
    one, five, _ = os.getloadavg()
    console.print(f"{base.name}: {args.trials} batch trials a setting; load {one:.2f} {five:.2f}")
    runs = {}
    for setting in SETTINGS:
        sc = with_values(base, {"campaign.data_stops": setting})
        runs[setting] = measure(sc, args.trials, args.seed)
    visits = list(dict.fromkeys((r["camera"], int(r["visit"])) for r in runs["all_leds"][0]))
    table = Table(
        title=f"{base.name}: camera position error, predicted vs batch Monte Carlo "
        "(RMS over the calibrated trials, mm; +- one standard error)"
    )
    table.add_column("visit")
    for setting in SETTINGS:
        for col in ("trials", "points", "predicted", "MC RMS", "pred/MC"):
            table.add_column(f"{setting}\n{col}", justify="right", no_wrap=True)
    for key in visits:
        cells = [f"{key[0]} #{key[1]}"]
        for setting in SETTINGS:
            v = visit_numbers(runs[setting][0], key)
            cells += [
                str(v["trials"]),
                f"{v['points']:.1f}",
                f"{v['predicted']:.2f}",
                f"{v['rms']:.2f} ± {v['se']:.2f}",
                f"{v['predicted'] / v['rms']:.2f}",
            ]
        table.add_row(*cells)
    console.print(table)
    speed = Table(
        title="Batch speed, one worker: the whole run (its plan recorded once), the plan alone, "
        "and the trials without the plan"
    )
    columns = ("data_stops", "trials", "stops", "wall s", "trials/s", "plan s", "trials/s w/o plan")
    for col in (*columns, "failures/trial"):
        speed.add_column(col, justify="right")
    for setting in SETTINGS:
        rows, wall, plan_s, stops = runs[setting]
        first = [r for r in rows if (r["camera"], int(r["visit"])) == visits[0]]
        failures = np.mean([r["failures"] for r in first])  # one row a trial
        speed.add_row(
            setting, str(args.trials), str(stops), f"{wall:.1f}", f"{args.trials / wall:.1f}",
            f"{plan_s:.1f}", f"{args.trials / (wall - plan_s):.1f}", f"{failures:.2f}",
        )  # fmt: skip
    console.print(speed)


if __name__ == "__main__":
    main()
