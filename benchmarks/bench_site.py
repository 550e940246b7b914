"""Planning time and memory of ``twin site`` on generated floors: hospital floors of 10, 30
and 100 cameras, and 60 x 60 m office floors of 30 cameras at 5 cm, with straight and with
ragged (SLAM-like) walls.

For each floor (:mod:`twin.planning.sample_floor`) the table gives the time to read the
map and to plan (stations, tour, route, boxes); the time of the whole ``twin site`` command
(map, plan, its noise-free geometric run, the repairs where that run drops a visit, the
scenario and figure written; the office floors only, unless ``--run-all``) and the repairs
it tried; the boxes the blocked floor is laid as (0.1 m grid), the route's length, the
cameras calibrated by the written plan's run, and the process's peak memory (each floor is
planned in a process of its own: ``ru_maxrss``). The ratio is the planning time per camera
against the first floor's, measured in the same run (the machine is shared: ratios travel,
seconds less so).

Target: the 60 x 60 m office floor through ``twin site`` (its run and repairs included) in
under 60 s and 2 GB.

Run: ``.venv/bin/python benchmarks/bench_site.py [--cameras 10 30 100] [--office 60 60]
[--rough 0 0.5] [--no-run]``.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import resource
import sys
import tempfile
import time
from dataclasses import dataclass

import numpy as np
from rich.console import Console
from rich.table import Table


@dataclass(frozen=True)
class Row:
    """One floor's measurements (seconds, GB, m)."""

    name: str
    cameras: int
    map_s: float
    plan_s: float
    run_s: float | None
    boxes: int
    route_m: float
    calibrated: int | None
    peak_gb: float
    refused: str = ""
    repairs: int | None = None


def _peak_gb() -> float:
    """This process's peak resident memory, GB (``ru_maxrss`` is in KiB on Linux)."""
    kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return kib * (1 if sys.platform != "darwin" else 1 / 1024) / 1024**2


def _measure(job: tuple[str, int, float, float, float, bool]) -> Row:
    """Plan one floor (in a fresh process): ``(kind, cameras, width, height, rough, run)``."""
    from twin.planning.floor_map import MapError
    from twin.planning.maps import load_map
    from twin.planning.sample_floor import write_floor, write_office_floor
    from twin.planning.site import plan_site, read_cameras
    from twin.planning.site_file import write_site

    kind, n, width, height, rough, run = job
    name = f"hospital {n}" if kind == "hospital" else f"office {width:g}x{height:g} r{rough:g}"
    with tempfile.TemporaryDirectory() as tmp:
        if kind == "hospital":
            grid, cams = write_floor(tmp, n)
        else:
            grid, cams = write_office_floor(tmp, width, height, n, seed=0, rough=rough)
        t0 = time.perf_counter()
        floor = load_map(grid)
        t1 = time.perf_counter()
        try:
            plan = plan_site(floor, read_cameras(cams), name="bench")
        except MapError as exc:
            t2 = time.perf_counter()
            return Row(name, n, t1 - t0, t2 - t1, None, 0, 0.0, None, _peak_gb(), str(exc))
        t2 = time.perf_counter()
        route = float(np.sum(np.linalg.norm(np.diff(plan.route, axis=0), axis=1)))
        run_s, calibrated, repairs = None, None, None
        if run:
            # The whole command as a user runs it: the map read, the plan, its noise-free
            # run and the repairs where that run drops a visit, the scenario and figure
            # written.
            t3 = time.perf_counter()
            written = write_site(grid, cams, f"{tmp}/site.toml", name="bench")
            run_s = time.perf_counter() - t3
            missed = len(written.plan.unreachable) + len(written.not_calibrated)
            calibrated, repairs = n - missed, len(written.repairs)
        return Row(
            name,
            n,
            t1 - t0,
            t2 - t1,
            run_s,
            len(plan.space.boxes),
            route,
            calibrated,
            _peak_gb(),
            repairs=repairs,
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cameras", type=int, nargs="*", default=[10, 30, 100])
    parser.add_argument("--office", type=float, nargs=2, default=[60.0, 60.0])
    parser.add_argument("--office-cameras", type=int, default=30)
    parser.add_argument("--rough", type=float, nargs="*", default=[0.0, 0.5])
    parser.add_argument("--no-run", action="store_true", help="skip the noise-free runs")
    parser.add_argument("--run-all", action="store_true", help="run the hospital floors too")
    args = parser.parse_args()
    jobs = [("hospital", n, 0.0, 0.0, 0.0, args.run_all and not args.no_run) for n in args.cameras]
    jobs += [
        ("office", args.office_cameras, *args.office, rough, not args.no_run)
        for rough in args.rough
    ]
    table = Table(title="twin site: planning time and memory (a process per floor)")
    for col in (
        "floor",
        "cameras",
        "map [s]",
        "plan [s]",
        "per camera [s]",
        "x first",
        "twin site [s]",
        "repairs",
        "boxes",
        "route [m]",
        "calibrated",
        "peak [GB]",
    ):
        table.add_column(col, justify="right")
    base = None
    notes = []
    context = multiprocessing.get_context("spawn")
    for job in jobs:
        with context.Pool(1) as pool:
            row = pool.apply(_measure, (job,))
        per = row.plan_s / row.cameras
        base = base or per
        table.add_row(
            row.name,
            str(row.cameras),
            f"{row.map_s:.2f}",
            f"{row.plan_s:.1f}",
            f"{per:.3f}",
            f"{per / base:.2f}",
            "-" if row.run_s is None else f"{row.run_s:.1f}",
            "-" if row.repairs is None else str(row.repairs),
            str(row.boxes) if not row.refused else "refused",
            f"{row.route_m:.0f}",
            "-" if row.calibrated is None else f"{row.calibrated}/{row.cameras}",
            f"{row.peak_gb:.2f}",
        )
        if row.refused:
            notes.append(f"{row.name}: {row.refused}")
    console = Console(width=160)
    console.print(table)
    for note in notes:
        console.print(note)
    console.print(f"load average {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
