"""The marker's surveying error against what the campaign predicts, by Monte Carlo at the
batch fidelity: each child's assembly built ``sigma`` off its drawing on every coordinate
(``noise.marker_geometry_m``) and the campaign told so (``marker.survey_sigma_m``).

For each sigma and each visit it prints the RMS true camera position error, the RMS of
its prediction (frame transfer and calibration, the survey's shared error included) and
their ratio (about 1 when the prediction holds it), the share of trials beyond three
predicted RMS, and the same for the global adjustment, which solves each child's survey
error as an unknown (its chi-square per degree of freedom, median over the trials).

    .venv/bin/python benchmarks/bench_survey.py [--trials 200] [--sigmas-mm 0 0.84 3]
        [--scenario scenarios/paper_hall.toml]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

import twin.sim  # noqa: F401  # isort: skip
from twin.batch.execute import BatchRun
from twin.batch.network import adjust_trials
from twin.batch.steps import record_plan
from twin.localization.adjustment import adjust_network
from twin.scenario import load_scenario
from twin.scenario.overrides import with_values

ROOT = Path(__file__).resolve().parents[1]


def _rms(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x**2))) if len(x) else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--sigmas-mm", type=float, nargs="+", default=[0.0, 0.84, 3.0])
    ap.add_argument("--scenario", default=str(ROOT / "scenarios" / "paper_hall.toml"))
    ap.add_argument("--seed", type=int, default=1000, help="the first trial's seed")
    args = ap.parse_args()
    console = Console(width=120)
    load = " ".join(f"{v:.2f}" for v in os.getloadavg())
    table = Table(title=f"{Path(args.scenario).stem}: {args.trials} batch trials a row")
    for column in (
        "sigma mm",
        "visit",
        "error mm",
        "predicted mm",
        "ratio",
        "> 3 pred.",
        "adjusted mm",
        "adj. pred. mm",
        "adj. ratio",
        "chi2/dof",
    ):
        table.add_column(column, justify="right")
    base = load_scenario(args.scenario)
    seeds = list(range(args.seed, args.seed + args.trials))
    start = time.perf_counter()
    for sigma_mm in args.sigmas_mm:
        sigma = 1e-3 * sigma_mm
        values = {"marker.survey_sigma_m": sigma, "noise.marker_geometry_m": sigma}
        plan = record_plan(with_values(base, values))
        run = BatchRun(plan, seeds, record_network=True)
        outcome = run.run()
        visits = list(outcome.calibrations)
        adjusted = adjust_trials(
            run.network, run.trials, plan.cameras, run.advertised_led_px, 0.0, visits
        )
        factors = []
        for k in range(min(run.trials, 20)):
            builder, _ = run.network.network(k, run.advertised_led_px)
            try:
                factors.append(adjust_network(builder.build()).variance_factor)
            except ValueError:
                continue
        chi2 = f"{np.median(factors):.3f}" if factors else "-"
        for (camera, visit), v in outcome.calibrations.items():
            error = np.where(v.calibrated, v.position_error, np.nan)
            predicted = np.hypot(v.predicted_transfer, v.predicted_calibration)
            a = adjusted[(camera, visit)]
            table.add_row(
                f"{sigma_mm:g}",
                f"{camera}.{visit}",
                f"{1e3 * _rms(error):.1f}",
                f"{1e3 * _rms(predicted):.1f}",
                f"{_rms(error) / _rms(predicted):.2f}",
                f"{100 * np.mean(error[v.calibrated] > 3 * predicted[v.calibrated]):.1f} %",
                f"{1e3 * _rms(a.position_error):.1f}",
                f"{1e3 * _rms(a.predicted):.1f}",
                f"{_rms(a.position_error) / _rms(a.predicted):.2f}",
                chi2,
            )
    console.print(table)
    wall = time.perf_counter() - start
    console.print(
        f"ratio: RMS error / RMS predicted. chi2/dof: median of the first 20 trials' "
        f"adjustments. {wall:.0f} s, load average {load}."
    )


if __name__ == "__main__":
    main()
