"""Planning time of ``twin site`` on generated hospital floors of 10, 30 and 100 cameras.

For each floor (:mod:`twin.planning.sample_floor`: about 22 m of corridor a camera) the
table gives the time to read the map, to plan (stations, tour, route, boxes) and the
route's length; the ratio is the time per camera against the smallest floor's, measured
in the same run (the machine is shared: ratios travel, seconds less so).

Run: ``.venv/bin/python benchmarks/bench_site.py [--cameras 10 30 100]``.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import numpy as np
from rich.console import Console
from rich.table import Table

from twin.planning.maps import load_map
from twin.planning.sample_floor import write_floor
from twin.planning.site import plan_site, read_cameras


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cameras", type=int, nargs="+", default=[10, 30, 100])
    args = parser.parse_args()
    table = Table(title="twin site planning time (one process)")
    for col in ("cameras", "map [s]", "plan [s]", "per camera [s]", "x smallest", "route [m]"):
        table.add_column(col, justify="right")
    base = None
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.cameras:
            grid, cams = write_floor(f"{tmp}/{n}", n)
            t0 = time.perf_counter()
            floor = load_map(grid)
            t1 = time.perf_counter()
            plan = plan_site(floor, read_cameras(cams), name=f"floor_{n}")
            t2 = time.perf_counter()
            per = (t2 - t1) / n
            base = base or per
            route = float(np.sum(np.linalg.norm(np.diff(plan.route, axis=0), axis=1)))
            table.add_row(
                str(n),
                f"{t1 - t0:.2f}",
                f"{t2 - t1:.1f}",
                f"{per:.3f}",
                f"{per / base:.2f}",
                f"{route:.0f}",
            )
    console = Console()
    console.print(table)
    console.print(f"load average {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
