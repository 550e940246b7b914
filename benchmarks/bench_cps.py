"""Accuracy and speed of CPS on the straight 85 m leapfrog with the Table I noise.

For two formations (children in line ahead of the parent, as in the paper's Fig. 6, and
side by side across the corridor) and two solvers (the paper's closed form, eq. 2, and
weighted least squares), prints the median and 90th percentile of the parent's final
position and yaw errors over a Monte Carlo, the predicted (1 sigma) position error, the
mean NEES of the final position (3 when the predicted covariance is right) and of the final
yaw (1), the number of runs stopped by a consistency error (on these clean data a false
alarm; about 4 expected per 500 runs at the default rate 1e-4), and the wall time of one
CPS step per run (children placed + parent solved, with covariance propagation; all runs
solved at once).

Run:  .venv/bin/python benchmarks/bench_cps.py [--runs 500] [--seed 0]
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from twin.instruments.total_station import ARCSEC
from twin.localization.leapfrog import Formation, LeapfrogConfig, evaluate, simulate_leapfrog


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=500, help="Monte Carlo runs per formation")
    parser.add_argument("--seed", type=int, default=0, help="random seed")
    args = parser.parse_args()

    base = LeapfrogConfig()
    print(
        f"Straight leapfrog: route {base.route_length:g} m, {base.n_steps} steps of "
        f"{base.step_length:g} m, {args.runs} runs, seed {args.seed}, Table I noise "
        f'(2 mm + 2 ppm, 5", 0.2 mm / 1" resolution), inclinometer 1"'
    )
    print(f"python {platform.python_version()}, numpy {np.__version__}, {platform.machine()}")
    header = (
        f"{'formation':<13}{'solver':<12}{'pos med':>9}{'pos p90':>9}{'pred 1s':>9}"
        f"{'yaw med':>9}{'yaw p90':>9}{'NEES p':>8}{'NEES y':>8}{'rej':>5}{'us/step':>9}"
    )
    print(header)
    print(
        f"{'':<25}{'[mm]':>9}{'[mm]':>9}{'[mm]':>9}{'[arcsec]':>9}{'[arcsec]':>9}"
        f"{'(3)':>8}{'(1)':>8}"
    )
    print("-" * len(header))
    start = time.perf_counter()
    for k, formation in enumerate(Formation):
        config = LeapfrogConfig(formation=formation)
        data = simulate_leapfrog(config, args.runs, np.random.default_rng([args.seed, k]))
        for solver in ("closed_form", "wls"):
            res = evaluate(data, solver)
            pos = res.position_error_norm * 1e3
            yaw = np.abs(res.yaw_error) / ARCSEC
            print(
                f"{formation.value:<13}{solver:<12}"
                f"{np.median(pos):9.1f}{np.percentile(pos, 90):9.1f}"
                f"{np.median(res.predicted_position_rms) * 1e3:9.1f}"
                f"{np.median(yaw):9.1f}{np.percentile(yaw, 90):9.1f}"
                f"{res.position_nees.mean():8.2f}{res.yaw_nees.mean():8.2f}"
                f"{len(res.rejected_runs):5d}{res.seconds_per_step * 1e6:9.0f}"
            )
    print(f"total {time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
