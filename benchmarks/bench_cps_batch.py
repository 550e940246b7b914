"""Throughput of the batched marker fit and CPS against the scalar code, trial by trial.

Two kinds of work, each at T = 1, 100 and 1000 trials per batch (``--trials``):

- marker fits: the pose, covariance and chi-square of a child's marker from its three
  cube shots (:func:`fit_marker_pose_batch` on T trials against :func:`fit_marker_pose`
  called once per trial);
- CPS steps: one leg of the straight leapfrog (the children placed, then the parent's
  pose solved, with the joint covariance propagated; observations built from the
  simulated points), for each solver (:class:`CpsBatch` on T trials against one
  :class:`CpsSequence` per trial).

Printed per row: trials per second of the batch (T times the calls per second), of the
scalar code one trial at a time in the same run (measured on ``--scalar-trials`` trials:
its rate does not depend on T), and their ratio. Each figure is the mean over repeated
calls lasting at least ``--seconds``. The load average is printed before and after,
because the machine may be shared.

Run:  .venv/bin/python benchmarks/bench_cps_batch.py [--trials 1 100 1000] [--seconds 1]
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from collections.abc import Callable

import numpy as np
from rich.console import Console
from rich.table import Table

from twin.instruments.marker import MarkerAssembly
from twin.instruments.marker_pose import fit_marker_pose, fit_marker_pose_batch
from twin.instruments.noise import cartesian_covariance
from twin.instruments.polar import polar2cartesian
from twin.instruments.shot import measure_points
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec
from twin.localization.joint_state import CpsBatch
from twin.localization.leapfrog import CHILDREN, LeapfrogConfig, LeapfrogData, simulate_leapfrog
from twin.localization.observation import ChildObservation, ChildObservationBatch
from twin.localization.sequence import CpsSequence

SOLVERS = ("closed_form", "wls")


def _rate(work: Callable[[], int], seconds: float) -> float:
    """Items per second of ``work`` (which returns how many items it did), repeated for at
    least ``seconds``."""
    work()  # warm up caches and imports
    done, start = 0, time.perf_counter()
    while True:
        done += work()
        elapsed = time.perf_counter() - start
        if elapsed >= seconds:
            return done / elapsed


def _cubes(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3, 3) noisy cubes of markers 3-25 m away and their (n, 3, 3, 3) covariances."""
    spec, incl, marker = TotalStationSpec(), InclinometerSpec(), MarkerAssembly()
    rng = np.random.default_rng(seed)
    heading = rng.uniform(-np.pi, np.pi, n)
    c, s = np.cos(heading), np.sin(heading)
    rot = np.zeros((n, 3, 3))
    rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 0], rot[:, 1, 1], rot[:, 2, 2] = c, -s, s, c, 1.0
    distance = rng.uniform(3, 25, n)
    floor = np.column_stack([distance * c, distance * s, np.full(n, -0.75)])
    cubes = np.einsum("tij,cj->tci", rot, marker.cubes_body) + floor[:, None]
    polar, _ = measure_points(cubes, 0.0, 0.0, spec, incl, rng)
    return polar2cartesian(polar), cartesian_covariance(polar, spec, incl)


def _cps_batch(data: LeapfrogData, solver: str) -> Callable[[], int]:
    def run() -> int:
        batch = CpsBatch(CHILDREN, data.n_runs, solver=solver, false_alarm_rate=None)
        for k in range(data.config.n_steps):
            for phase, (points, cov) in enumerate(
                ((data.before, data.before_cov), (data.after, data.after_cov))
            ):
                obs = [
                    ChildObservationBatch(name, points[:, k, i], cov[:, k, i])
                    for i, name in enumerate(CHILDREN)
                ]
                (batch.children_moved if phase == 0 else batch.parent_moved)(obs)
        return data.n_runs * data.config.n_steps

    return run


def _cps_scalar(data: LeapfrogData, solver: str) -> Callable[[], int]:
    def run() -> int:
        for r in range(data.n_runs):
            seq = CpsSequence(CHILDREN, solver=solver, false_alarm_rate=None)
            for k in range(data.config.n_steps):
                for phase, (points, cov) in enumerate(
                    ((data.before, data.before_cov), (data.after, data.after_cov))
                ):
                    obs = [
                        ChildObservation(name, points[r, k, i], cov[r, k, i])
                        for i, name in enumerate(CHILDREN)
                    ]
                    (seq.children_moved if phase == 0 else seq.parent_moved)(obs)
        return data.n_runs * data.config.n_steps

    return run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, nargs="+", default=[1, 100, 1000],
                        help="trials per batch (default: 1 100 1000)")  # fmt: skip
    parser.add_argument("--scalar-trials", type=int, default=50,
                        help="trials the scalar code runs one at a time (default: 50)")  # fmt: skip
    parser.add_argument("--seconds", type=float, default=1.0,
                        help="least time per measurement, s (default: 1)")  # fmt: skip
    parser.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    args = parser.parse_args()

    console = Console(width=110)
    marker = MarkerAssembly()
    config = LeapfrogConfig()
    load_before = os.getloadavg()
    rows = []

    cubes, cov = _cubes(args.scalar_trials, args.seed)

    def scalar_fits() -> int:
        for i in range(args.scalar_trials):
            fit_marker_pose(cubes[i], marker, cov[i])
        return args.scalar_trials

    scalar = _rate(scalar_fits, args.seconds)
    for n in args.trials:
        batch_cubes, batch_cov = _cubes(n, args.seed)

        def batch_fits(c: np.ndarray = batch_cubes, v: np.ndarray = batch_cov) -> int:
            return fit_marker_pose_batch(c, marker, v).rms_residual.size

        rows.append(("marker fits", n, _rate(batch_fits, args.seconds), scalar))

    small = simulate_leapfrog(config, args.scalar_trials, np.random.default_rng(args.seed))
    for solver in SOLVERS:
        scalar = _rate(_cps_scalar(small, solver), args.seconds)
        for n in args.trials:
            data = simulate_leapfrog(config, n, np.random.default_rng(args.seed))
            batch = _rate(_cps_batch(data, solver), args.seconds)
            rows.append((f"CPS steps, {solver}", n, batch, scalar))
    load_after = os.getloadavg()

    table = Table(title="Batched marker fits and CPS steps against the scalar code")
    for col in ("work", "T", "batch \\[trials/s]", "scalar \\[trials/s]", "batch / scalar"):
        table.add_column(col, justify="right")
    for work, n, batch, scalar in rows:
        table.add_row(work, f"{n:,}", f"{batch:,.0f}", f"{scalar:,.0f}", f"{batch / scalar:.1f}")
    console.print(table)
    console.print(
        f"A CPS step is one leg: two children placed, the parent solved ({config.n_steps} "
        f"legs a run). Scalar rates from {args.scalar_trials} trials one at a time."
    )
    console.print(
        f"python {platform.python_version()}, numpy {np.__version__}, {os.cpu_count()} CPUs; "
        f"load average (1, 5, 15 min) {', '.join(f'{v:.2f}' for v in load_before)} before, "
        f"{', '.join(f'{v:.2f}' for v in load_after)} after"
    )


if __name__ == "__main__":
    main()
