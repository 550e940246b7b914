"""Fit the paper hall's unknown error sources to the paper's measurements.

Runs the batch fidelity on ``scenarios/paper_hall_as_built.toml`` (its geometry; its noise
values are replaced) with the sources of
:data:`twin.montecarlo.error_fit.PAPER_HALL_SOURCES` adjusted until the twin's medians
match Table III and the repeatability of cameras 1 and 2 (the objective and its weights:
:mod:`twin.montecarlo.error_fit`), prints the fitted values with their standard errors
and whether they are plausible, then checks the result on fresh seeds and prints the
twin beside the paper. The values found are those of ``scenarios/paper_hall_as_built.toml``.

    .venv/bin/python examples/fit_paper_hall.py [--trials 300] [--workers 2]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from twin.montecarlo.error_fit import PAPER_HALL_SOURCES, BatchEvaluator, fit_error_model
from twin.montecarlo.paper_targets import against_paper
from twin.scenario import load_scenario


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scenario", default="scenarios/paper_hall_as_built.toml")
    parser.add_argument("--trials", type=int, default=300)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=1, help="master seed of the fit's trials")
    parser.add_argument("--check-seed", type=int, default=2, help="master seed of the check")
    parser.add_argument(
        "--start",
        type=float,
        nargs=len(PAPER_HALL_SOURCES),
        default=(0.55, 0.65, 0.9, 1.9),
        help="starting values, in the order and units of the sources",
    )
    args = parser.parse_args()
    scenario = load_scenario(args.scenario)
    t0 = time.perf_counter()

    def show(values: dict[str, float], cost: float) -> None:
        shown = ", ".join(f"{k} = {v:.3f}" for k, v in values.items())
        print(f"  [{time.perf_counter() - t0:6.0f} s] {shown}: sum of squares {cost:.2f}")

    with BatchEvaluator(scenario, args.trials, args.seed, args.workers) as evaluate:
        fit = fit_error_model(evaluate, PAPER_HALL_SOURCES, args.start, progress=show)
        print(f"\n{fit.evaluations} evaluations of {args.trials} trials; {fit.message}")
        print("\n| source | fitted | standard error | plausible range | plausible |")
        print("|---|---|---|---|---|")
        for p, v, s, ok in zip(fit.parameters, fit.values, fit.std, fit.plausible(), strict=True):
            lo, hi = p.plausible
            print(
                f"| {p.key} | {v:.3f} {p.unit} | {s:.3f} {p.unit} | {lo:g}-{hi:g} "
                f"{p.unit} | {'yes' if ok else 'no'} |"
            )
        print("\ncorrelation of the fitted values:")
        print(np.array2string(fit.correlation, precision=2))
        print("\n| target | residual / spread | spread of log |")
        print("|---|---|---|")
        for t, r, s in zip(fit.targets, fit.residuals, fit.spread, strict=True):
            print(f"| {t.name} | {r:+.2f} | {s:.2f} |")
    with BatchEvaluator(scenario, args.trials, args.check_seed, args.workers) as check:
        rows = check(fit.scenario_values())
    print(f"\nCheck on fresh seeds (master seed {args.check_seed}, {args.trials} trials):\n")
    print("| entry | paper | twin median | twin 10-90 % | paper's percentile | matched |")
    print("|---|---|---|---|---|---|")
    for e in against_paper(rows):
        print(
            f"| {e['name']} | {e['paper']:.2f} | {e['median']:.2f} | {e['p10']:.2f}-"
            f"{e['p90']:.2f} | {e['paper_percentile']:.0f} | {'yes' if e['matched'] else 'no'} |"
        )
    print("\nscenario values (SI):", fit.scenario_values())
    print(f"wall time {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
