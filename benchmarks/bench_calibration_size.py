"""Time and memory of ``twin calibrate`` against the number of points.

For each size (1,000, 10,000 and 100,000 points by default) a CSV of correspondences is
written for a camera like the paper's camera 1 (points through its whole view at 3-15 m,
0.3 px pixel noise), and one fresh process runs ``twin calibrate`` on it with ``--json``:
reading the file, the closed-form stages, the full optimisation, the covariance, the
metrics and the writing. The process first calibrates 100 points (imports, caches); its
resident memory (RSS) after that is the base. Printed per size: the wall time of the run,
the process's peak RSS, the peak above the base (what the calibration itself took), and
both as ratios against the first size of the same invocation. Linear growth shows as
ratios at most the ratio of the point counts (10, 100); the load average is printed because
the machine may be shared.

Run: ``.venv/bin/python benchmarks/bench_calibration_size.py [--sizes N ...] [--model M]``
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from calib.io import write_points_csv
from calib.synthetic import paper_camera, points_in_view


def _calibrate(csv: Path, model: str) -> tuple[int, float]:
    """``twin calibrate`` on ``csv`` in this process: exit code and wall time, s."""
    from twin.cli import main

    out_json = csv.with_suffix(".result.json")
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        code = main(["calibrate", str(csv), "--image-size", "320", "240", "--model", model,
                     "--json", str(out_json)])  # fmt: skip
    return code, time.perf_counter() - t0


def _child(csv: str, model: str) -> None:
    """Calibrate a small file (imports, caches), then ``csv``; print time and memory."""
    warm_up = Path(csv).with_name("warm_up.csv")
    _write_points(warm_up, 100, 0)
    _calibrate(warm_up, model)
    base_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    code, wall = _calibrate(Path(csv), model)
    out_json = Path(csv).with_suffix(".result.json")
    peak_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    n = json.loads(out_json.read_text())["n_points"]
    print(json.dumps({"code": code, "wall_s": wall, "peak_mb": peak_kb / 1024,
                      "base_mb": base_kb / 1024, "n_points": n}))  # fmt: skip


def _write_points(path: Path, n_points: int, seed: int) -> None:
    cam = paper_camera(1)
    rng = np.random.default_rng(seed)
    pts = points_in_view(cam, n_points, rng)
    uv = cam.project(pts) + rng.normal(0.0, 0.3, (n_points, 2))
    write_points_csv(path, pts, uv)


def _measure(csv: Path, model: str) -> dict[str, float]:
    proc = subprocess.run(
        [sys.executable, __file__, "--child", str(csv), "--model", model],
        capture_output=True,
        text=True,
        check=False,
    )
    if proc.returncode != 0:
        raise SystemExit(f"the calibration of {csv} failed:\n{proc.stderr}")
    return json.loads(proc.stdout.splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1_000, 10_000, 100_000],
                        help="numbers of points; the first is the baseline of the ratios "
                        "(default: 1000 10000 100000)")  # fmt: skip
    parser.add_argument("--model", choices=["tsai", "opencv"], default="tsai",
                        help="camera model (default: tsai)")  # fmt: skip
    parser.add_argument("--seed", type=int, default=1, help="random seed (default: 1)")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        _child(args.child, args.model)
        return

    console = Console(width=120)
    load_before = os.getloadavg()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.sizes:
            csv = Path(tmp) / f"points_{n}.csv"
            _write_points(csv, n, args.seed)
            rows.append((n, _measure(csv, args.model)))
    load_after = os.getloadavg()

    table = Table(title=f"twin calibrate --model {args.model}: time and memory against points")
    for col in ("points", "time \\[s]", "time ratio", "peak RSS [MB]", "above base [MB]",
                "memory ratio", "points ratio"):  # fmt: skip
        table.add_column(col, justify="right")
    n0, r0 = rows[0]
    own0 = r0["peak_mb"] - r0["base_mb"]
    for n, r in rows:
        own = r["peak_mb"] - r["base_mb"]
        table.add_row(
            f"{n:,}",
            f"{r['wall_s']:.2f}",
            f"{r['wall_s'] / r0['wall_s']:.1f}",
            f"{r['peak_mb']:.0f}",
            f"{own:.0f}",
            f"{own / own0:.1f}" if own0 > 0 else "-",
            f"{n / n0:.0f}",
        )
    console.print(table)
    console.print(
        f"{os.cpu_count()} CPUs; load average (1, 5, 15 min) "
        f"{', '.join(f'{v:.2f}' for v in load_before)} before, "
        f"{', '.join(f'{v:.2f}' for v in load_after)} after"
    )


if __name__ == "__main__":
    main()
