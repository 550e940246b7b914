"""Batched Tsai calibration: calibrations per second of calibrate_tsai_batch for T trials
at once, against calibrate_tsai one data set at a time, measured in the same run.

The data are a Monte-Carlo visit of the paper's camera 1: 70 LED points, each trial with
its own 0.3 px pixel noise and 1.5 mm noise on the 3D points; the batch starts every trial
from the noise-free calibration of the visit (as the Monte-Carlo batch does). The
baseline, calibrate_tsai, also runs its closed-form stages. BLAS runs on one thread (set
before numpy is imported), so both use one core. Also printed: the minor page faults
per batch (memory glibc's allocator returned to the system and faults in again; the
batch's ``block`` keeps them low), and the largest difference between the two solutions
over the baseline's trials, in the baseline's standard deviations. ``--no-trim`` runs
again with glibc told to keep its memory (MALLOC_TRIM_THRESHOLD_, MALLOC_MMAP_THRESHOLD_).

Run: ``.venv/bin/python benchmarks/bench_tsai_batch.py [--seconds S] [--baseline N]
[--block B] [--no-trim]``
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import resource
import sys
import time

import numpy as np
from rich.console import Console
from rich.table import Table

from calib import calibrate_tsai
from calib.synthetic import led_points, paper_camera
from calib.tsai_lm import calibrate_tsai_batch

SIZES = (1, 10, 100, 1000)
N_POINTS, SIGMA_PX, SIGMA_M = 70, 0.3, 1.5e-3


def visit(trials: int, seed: int) -> tuple:
    """(camera, noise-free calibration, points (T, N, 3), pixels (T, N, 2))."""
    cam = paper_camera(1)
    rng = np.random.default_rng(seed)
    pts = led_points(cam, N_POINTS, rng)
    uv = cam.project(pts)
    start = calibrate_tsai(pts, uv, cam.image_size).camera
    points = pts + rng.normal(0.0, SIGMA_M, (trials, *pts.shape))
    pixels = uv + rng.normal(0.0, SIGMA_PX, (trials, *uv.shape))
    return cam, start, points, pixels


NO_TRIM = {"MALLOC_TRIM_THRESHOLD_": "1000000000", "MALLOC_MMAP_THRESHOLD_": "1000000000"}


def _faults() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt


def timed(fn, seconds: float) -> tuple[float, float, float, object]:
    """Median wall and CPU time and mean minor page faults of repeated calls for about
    ``seconds``; the last result."""
    result = fn()  # warm-up
    walls, cpus = [], []
    f0 = _faults()
    t_end = time.perf_counter() + seconds
    while time.perf_counter() < t_end or len(walls) < 3:
        w0, c0 = time.perf_counter(), time.process_time()
        result = fn()
        walls.append(time.perf_counter() - w0)
        cpus.append(time.process_time() - c0)
    faults = (_faults() - f0) / len(walls)
    return float(np.median(walls)), float(np.median(cpus)), faults, result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=2.0, help="time per setting, s")
    ap.add_argument("--baseline", type=int, default=100, help="calibrate_tsai data sets")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--block", type=int, default=64, help="trials fitted together")
    ap.add_argument("--no-trim", action="store_true", help="glibc keeps its memory")
    args = ap.parse_args()
    if args.no_trim and any(os.environ.get(k) != v for k, v in NO_TRIM.items()):
        os.execve(sys.executable, [sys.executable, *sys.argv], {**os.environ, **NO_TRIM})
    console = Console(width=140)
    load_before = os.getloadavg()
    cam, start, points, pixels = visit(max(SIZES), args.seed)
    size = cam.image_size

    nb = args.baseline
    t0, c0 = time.perf_counter(), time.process_time()
    refs = [calibrate_tsai(points[k], pixels[k], size) for k in range(nb)]
    base_wall, base_cpu = (time.perf_counter() - t0) / nb, (time.process_time() - c0) / nb
    base_rate = 1.0 / base_wall

    table = Table(
        title=f"calibrate_tsai_batch: camera 1, {N_POINTS} points, {SIGMA_PX} px and "
        f"{SIGMA_M * 1e3:g} mm noise, blocks of {args.block}"
        + (", glibc not trimming" if args.no_trim else "")
    )
    for col in ("trials T", "ms / batch", "CPU ms / batch", "calibrations / s", "vs one at a time",
                "page faults / batch", "iterations (median, max)", "converged"):  # fmt: skip
        table.add_column(col, justify="right")
    table.add_row(
        "calibrate_tsai", f"{base_wall * 1e3:.2f}", f"{base_cpu * 1e3:.2f}",
        f"{base_rate:,.0f}", "1.0", "-", "-", "-",
    )  # fmt: skip
    for n in SIZES:
        wall, cpu, faults, res = timed(
            lambda n=n: calibrate_tsai_batch(points[:n], pixels[:n], size, start, block=args.block),
            args.seconds,
        )
        table.add_row(
            str(n), f"{wall * 1e3:.2f}", f"{cpu * 1e3:.2f}", f"{n / wall:,.0f}",
            f"{n / wall / base_rate:.1f}", f"{faults:,.0f}",
            f"{np.median(res.iterations):.0f}, {res.iterations.max()}",
            f"{res.converged.mean():.1%}",
        )  # fmt: skip
    console.print(table)

    batch = calibrate_tsai_batch(points[:nb], pixels[:nb], size, start)
    values = np.array([r.values for r in refs])
    diff = batch.values - values
    diff[:, 5:8] = np.angle(np.exp(1j * diff[:, 5:8]))
    std = np.array([r.std for r in refs])
    pos_std = np.sqrt(np.diagonal(batch.position_covariance, axis1=1, axis2=2))
    console.print(
        f"agreement with calibrate_tsai over {nb} trials: parameters within "
        f"{np.abs(diff / std).max():.1e} of their standard deviations, position standard "
        f"deviations within {np.abs(pos_std / std[:, 8:11] - 1).max():.1e} relative"
    )
    load_after = os.getloadavg()
    console.print(
        f"{os.cpu_count()} CPUs, BLAS threads {os.environ['OPENBLAS_NUM_THREADS']}; load "
        f"average (1, 5, 15 min) {', '.join(f'{v:.2f}' for v in load_before)} before, "
        f"{', '.join(f'{v:.2f}' for v in load_after)} after"
    )


if __name__ == "__main__":
    main()
