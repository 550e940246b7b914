"""Real and generated building floors through ``twin site`` and ``twin run``, as a user
brings them: does each plan without help, and are its cameras calibrated?

Sites: the real maps under ``benchmarks/sites/maps/`` (sources and licences in
``benchmarks/sites/SOURCES.md``; nothing is downloaded), and generated families
(:mod:`twin.planning.floor_shapes`): corridors 2.0-4.0 m wide turning by 45-180 degrees,
dead-end rooms, doorways, some with a SLAM map's flaws. Cameras are placed by
:func:`twin.planning.camera_layout.place_cameras` (seed 0): along the floor's medial axis,
3 m up, looking 30 degrees down along it, 6-30 a site.

Per site, as a user would run it (each a separate process):

1. ``python -m twin.cli site map.yaml --cameras cameras.yaml --out site.toml``, no start
   given: planned (exit 0 or 1, the scenario written) or not (the error); its wall time
   and peak memory (the process's maximum RSS), its own noise-free run included;
2. ``python -m twin.cli run site.toml --fidelity geometric --no-noise``: the plan run
   noise-free (did it complete, or abort?);
3. ``python -m twin.cli run site.toml --fidelity geometric --seed S`` for each seed.

A camera counts when its floor view (its image's rays met with the floor, walls not hiding
them) holds floor reachable from the start (the start of the plan; the largest reachable
region where there is no plan) at the robots' clearance; it is calibrated in a run when a
calibration of it is delivered with a world-frame position error under 100 mm. The median
and worst errors are over every calibration delivered (a camera's second visit included).
The summary row checks the targets: every site plans without a given start, at least 99 %
of the cameras calibrated over the seeds, and no abort in the seeds' runs of a plan whose
noise-free run completed.

Run: ``.venv/bin/python benchmarks/bench_sites.py [--sites NAME ...] [--seeds 1 2 3 4 5]
[--jobs 2] [--timeout 600] [--camera-height 3] [--keep DIR] [--json out.json]``; ``--list``
names the sites. Each site's commands run one after another in one of ``--jobs`` worker
processes; ``--keep`` keeps each site's map, cameras, scenario and runs.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import time
import tomllib
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from rich.console import Console
from rich.table import Table
from shapely.geometry import Point

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # this checkout's twin, in this process and its workers
MAPS = Path(__file__).resolve().parent / "sites" / "maps"
CALIBRATED_MM = 100.0
"""A delivered calibration counts when its world-frame position error is under this, mm."""
TARGET_CALIBRATED = 0.99
DEFAULT_SEEDS = (1, 2, 3, 4, 5)


def _generated() -> dict[str, Callable[[], Any]]:
    """The generated families: name -> (shape, SLAM flaws)."""
    from twin.planning import floor_shapes as fs

    sites: dict[str, Callable[[], Any]] = {}
    for width, turn in ((2.0, 45), (2.4, 90), (3.0, 90), (3.0, 135), (4.0, 90), (2.4, 180)):
        sites[f"turn_{turn}deg_w{width:g}"] = lambda w=width, t=turn: (
            fs.corridor_turn(w, t),
            False,
        )
    sites["u_turn_w4"] = lambda: (fs.u_turn(4.0), False)
    for width in (2.4, 4.0):
        sites[f"dead_end_w{width:g}"] = lambda w=width: (fs.dead_end(w), False)
    for door in (1.0, 1.2):
        sites[f"doorway_{door:g}m"] = lambda d=door: (fs.doorway(door=d), False)
    sites["slam_turn_90deg_w3"] = lambda: (fs.corridor_turn(3.0, 90), True)
    sites["slam_dead_end_w3"] = lambda: (fs.dead_end(3.0), True)
    sites["slam_doorway_1m"] = lambda: (fs.doorway(door=1.0), True)
    return sites


def site_names() -> list[str]:
    """Every site: the real maps (by folder), then the generated ones."""
    real = sorted(p.name for p in MAPS.iterdir() if (p / "map.yaml").is_file())
    return real + list(_generated())


@dataclass
class SiteResult:
    """One site's row (see the module). Times in s, memory in MB, errors in mm, route in m."""

    site: str
    kind: str
    cameras: int = 0
    counted: int = 0
    planned: bool = False
    error: str = ""
    plan_s: float = math.nan
    plan_mb: float = math.nan
    route_m: float = math.nan
    noise_free: str = "-"
    calibrated: int = 0
    runs: int = 0
    aborts: int = 0
    errors_mm: list[float] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def _command(args: list[str], timeout: float) -> tuple[int, str, float, float]:
    """Run ``python -m twin.cli ARGS`` from the repository: (exit code, its output, wall
    time s, peak memory MB). A command past ``timeout`` is killed (exit code -9)."""
    t0 = time.perf_counter()
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"), "COLUMNS": "200"}
    with tempfile.TemporaryFile("w+") as out:
        proc = subprocess.Popen(
            [sys.executable, "-m", "twin.cli", *args],
            cwd=ROOT,
            stdout=out,
            stderr=subprocess.STDOUT,
            env=env,
            text=True,
        )
        deadline = time.monotonic() + timeout
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.monotonic() > deadline:
                proc.kill()
                pid, status, usage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.05)
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        text = out.read()
    return proc.returncode, text, time.perf_counter() - t0, usage.ru_maxrss / 1024.0


def _last_error(text: str) -> str:
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    for k, ln in enumerate(lines):
        if ln.startswith("error:") or "Traceback" in ln:
            return re.sub(r"\s+", " ", " ".join(lines[k : k + 2]))[:400]
    return re.sub(r"\s+", " ", " ".join(lines[-3:]))[:300]


def _write_map(name: str, folder: Path) -> Path:
    """The site's map.yaml: the stored one, or the generated one written into ``folder``."""
    if (MAPS / name / "map.yaml").is_file():
        return MAPS / name / "map.yaml"
    from twin.planning.floor_shapes import write_ros_map

    shape, flaws = _generated()[name]()
    return write_ros_map(shape, folder, flaws=flaws, seed=0)


def _counted(
    floor: Any, cameras: list[dict[str, Any]], start: tuple[float, float] | None
) -> set[str]:
    """The cameras whose floor views hold floor reachable from ``start`` (map frame, m; the
    largest reachable region when None) at the robots' clearance."""
    from twin.planning.maps import polygons_of
    from twin.planning.site import PASSAGE_CLEARANCE
    from twin.scenario.geometry import floor_view
    from twin.scenario.loader import validate_model
    from twin.scenario.schema import CameraConfig

    pieces = polygons_of(floor.reachable(PASSAGE_CLEARANCE))
    if not pieces:
        return set()
    if start is not None:
        here = [p for p in pieces if p.covers(Point(*start))]
        region = here[0] if here else min(pieces, key=lambda p: p.distance(Point(*start)))
    else:
        region = max(pieces, key=lambda p: p.area)
    out = set()
    shapely.prepare(floor.free)
    for cam in cameras:
        view = floor_view(validate_model(CameraConfig, cam).tsai(), 0.0, max_range=60.0)
        # The floor the camera itself sees: a ROS map's blocked cells reach the ceiling, so
        # a sight line to the floor is clear where it stays over free floor.
        lines = (
            shapely.linestrings([[cam["position"][:2], p[:2]] for p in view]) if len(view) else []
        )
        seen = [p for p, line in zip(view, lines, strict=True) if floor.free.covers(line)]
        if any(region.covers(Point(*p[:2])) for p in seen):
            out.add(str(cam["name"]))
    return out


def run_site(
    name: str, seeds: tuple[int, ...], timeout: float, keep: Path | None, height: float
) -> SiteResult:
    """Plan and run one site (see the module)."""
    from twin.planning.camera_layout import place_cameras, write_cameras
    from twin.planning.maps import load_map

    kind = "real" if (MAPS / name / "map.yaml").is_file() else "generated"
    result = SiteResult(name, kind)
    with tempfile.TemporaryDirectory(prefix=f"site-{name}-") as tmp:
        work = keep / name if keep else Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        grid = _write_map(name, work / "map")
        floor = load_map(grid)
        cameras = place_cameras(floor, seed=0, height=height)
        result.cameras = len(cameras)
        cams = write_cameras(cameras, work / "cameras.yaml", f"{name}: placed by camera_layout")
        site = work / "site.toml"
        code, text, wall, mb = _command(
            ["site", str(grid), "--cameras", str(cams), "--out", str(site), "--overwrite"], timeout
        )
        result.plan_s, result.plan_mb = wall, mb
        result.planned = code in (0, 1) and site.is_file()
        start = None
        if not result.planned:
            result.error = f"exit {code}: {_last_error(text)}"
        else:
            scenario = tomllib.loads(site.read_text())
            pose = scenario.get("site", {}).get("map_pose", [0.0, 0.0, 0.0])
            start = (float(pose[0]), float(pose[1]))
            route = np.asarray(scenario["route"]["waypoints"], dtype=float)
            result.route_m = float(np.sum(np.linalg.norm(np.diff(route, axis=0), axis=1)))
        counted = _counted(floor, cameras, start)
        result.counted = len(counted)
        if not result.planned:
            result.runs = len(seeds)
            return result
        runs = [("noise-free", ["--no-noise"])] + [(str(s), ["--seed", str(s)]) for s in seeds]
        for label, extra in runs:
            out = work / f"run-{label}"
            code, text, _, _ = _command(
                [
                    "run",
                    str(site),
                    "--fidelity",
                    "geometric",
                    "--no-report",
                    "--overwrite",
                    "--out",
                    str(out),
                    *extra,
                ],
                timeout,
            )
            res_file = out / "results.json"
            res = json.loads(res_file.read_text()) if res_file.is_file() else None
            if label == "noise-free":
                result.noise_free = _noise_free(code, res, text)
                continue
            result.runs += 1
            if res is None:
                result.notes.append(f"seed {label}: exit {code}: {_last_error(text)}")
                continue
            if res.get("aborted"):
                result.aborts += 1
                result.notes.append(f"seed {label}: aborted: {str(res['aborted'])[:200]}")
            best: dict[str, float] = {}
            for cal in res.get("calibrations", []):
                mm = (cal.get("truth") or {}).get("position_error_mm")
                if mm is not None and math.isfinite(mm):
                    result.errors_mm.append(float(mm))
                    best[cal["camera"]] = min(best.get(cal["camera"], math.inf), float(mm))
            result.calibrated += sum(
                1 for cam, mm in best.items() if mm < CALIBRATED_MM and cam in counted
            )
    return result


def _noise_free(code: int, res: dict[str, Any] | None, text: str) -> str:
    if res is None:
        return f"exit {code}: {_last_error(text)}"
    if res.get("aborted"):
        return f"aborted: {str(res['aborted'])[:120]}"
    skipped = res.get("skipped_visits") or []
    return "complete" if not skipped else f"{len(skipped)} visit(s) skipped"


def _safe(
    name: str, seeds: tuple[int, ...], timeout: float, keep: Path | None, height: float
) -> SiteResult:
    try:
        return run_site(name, seeds, timeout, keep, height)
    except Exception as exc:  # the benchmark reports what broke and goes on
        return SiteResult(name, "?", error=f"benchmark: {type(exc).__name__}: {exc}"[:300])


def _fmt(v: float, spec: str) -> str:
    return "-" if not math.isfinite(v) else format(v, spec)


def print_table(
    results: list[SiteResult], seeds: tuple[int, ...], wall: float, height: float
) -> None:
    console = Console(width=200)
    table = Table(
        title=f"twin site + twin run (geometric), seeds {list(seeds)}, cameras {height:g} m up"
    )
    cols = ("site", "kind", "cams", "counted", "planned", "plan [s]", "peak [MB]", "route [m]")
    cols += ("noise-free run", "calibrated", "median [mm]", "worst [mm]", "aborts")
    for col in cols:
        table.add_column(col, justify="left" if col in ("site", "noise-free run") else "right")
    for r in results:
        errs = np.asarray(r.errors_mm)
        denom = r.counted * r.runs
        table.add_row(
            r.site,
            r.kind,
            str(r.cameras),
            str(r.counted),
            "yes" if r.planned else "[red]no[/red]",
            _fmt(r.plan_s, ".1f"),
            _fmt(r.plan_mb, ".0f"),
            _fmt(r.route_m, ".0f"),
            r.noise_free,
            f"{r.calibrated}/{denom}" + (f" {100 * r.calibrated / denom:.0f}%" if denom else ""),
            _fmt(float(np.median(errs)) if errs.size else math.nan, ".1f"),
            _fmt(float(errs.max()) if errs.size else math.nan, ".0f"),
            str(r.aborts),
        )
    planned = sum(r.planned for r in results)
    cal = sum(r.calibrated for r in results)
    denom = sum(r.counted * r.runs for r in results)
    bad_aborts = sum(r.aborts for r in results if r.noise_free == "complete")
    rate = cal / denom if denom else math.nan
    ok = (planned == len(results), rate >= TARGET_CALIBRATED, bad_aborts == 0)
    mark = ["[green]met[/green]" if x else "[red]not met[/red]" for x in ok]
    table.add_section()
    table.add_row(
        "all",
        "",
        str(sum(r.cameras for r in results)),
        str(sum(r.counted for r in results)),
        f"{planned}/{len(results)} {mark[0]}",
        _fmt(max((r.plan_s for r in results), default=math.nan), ".1f"),
        _fmt(max((r.plan_mb for r in results), default=math.nan), ".0f"),
        "",
        f"aborts where noise-free complete: {bad_aborts} {mark[2]}",
        f"{cal}/{denom} {_fmt(100 * rate, '.1f')}% {mark[1]}",
        "",
        "",
        str(sum(r.aborts for r in results)),
    )
    console.print(table)
    console.print(
        "targets: every site plans without a given start; >= 99 % of the counted cameras "
        "calibrated (< 100 mm) over the seeds; no abort where the plan ran noise-free"
    )
    for r in results:
        for line in ([r.error] if r.error else []) + r.notes:
            console.print(f"  {r.site}: {line}", markup=False)
    load = " ".join(f"{v:.2f}" for v in os.getloadavg())
    console.print(f"wall time {wall:.0f} s; load average {load} (1, 5, 15 min)")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sites", nargs="+", metavar="NAME", help="sites to run (default: all)")
    parser.add_argument("--seeds", type=int, nargs="+", default=list(DEFAULT_SEEDS))
    parser.add_argument("--jobs", type=int, default=2, help="sites run at once (processes)")
    parser.add_argument("--timeout", type=float, default=600.0, help="per command, s")
    parser.add_argument(
        "--camera-height", type=float, default=3.0, help="the cameras' height, m (default 3)"
    )
    parser.add_argument("--keep", type=Path, help="keep each site's files under this folder")
    parser.add_argument("--json", type=Path, help="write the rows as JSON here")
    parser.add_argument("--list", action="store_true", help="name the sites and stop")
    args = parser.parse_args(argv)
    names = site_names()
    if args.list:
        print("\n".join(names))
        return 0
    wanted = args.sites or names
    unknown = sorted(set(wanted) - set(names))
    if unknown:
        parser.error(f"--sites: unknown {unknown}; known: {', '.join(names)}")
    if args.jobs < 1:
        parser.error(f"--jobs: expected at least 1, got {args.jobs}")
    seeds = tuple(args.seeds)
    load = " ".join(f"{v:.2f}" for v in os.getloadavg())
    Console().print(f"{len(wanted)} sites, seeds {list(seeds)}, {args.jobs} jobs; load {load}")
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        futures = [
            pool.submit(_safe, n, seeds, args.timeout, args.keep, args.camera_height)
            for n in wanted
        ]
        results = [f.result() for f in futures]
    print_table(results, seeds, time.perf_counter() - t0, args.camera_height)
    if args.json:
        args.json.write_text(json.dumps([asdict(r) for r in results], indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
