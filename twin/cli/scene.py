"""``twin scene``: validate a scenario, build its MuJoCo world, summarise it, export it."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import shapely
from rich.console import Console
from rich.table import Table

from twin.outputs import check_file_target
from twin.scenario import Scenario, ScenarioError, load_scenario
from twin.scenario.geometry import floor_view_corners


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``scene`` subcommand."""
    p = sub.add_parser(
        "scene",
        help="validate a scenario, build its MuJoCo world and summarise it",
        description=(
            "Validate a scenario file, build its MuJoCo scene, and print the robots, the "
            "cameras with their fields of view on the floor, and the route. With --export, "
            "write the compiled scene as an MJCF file that loads on its own."
        ),
    )
    p.add_argument("scenario", type=Path, help="scenario file (.toml or .yaml)")
    p.add_argument(
        "--export",
        type=Path,
        metavar="FILE.xml",
        help="write the scene as MJCF (default: do not write it)",
    )
    p.set_defaults(func=run)


def load_or_report(path: Path, console: Console) -> Scenario | None:
    """The scenario, or None after printing why it is invalid (to stderr)."""
    try:
        return load_scenario(path)
    except ScenarioError as exc:
        Console(stderr=True, highlight=False).print(str(exc), markup=False, soft_wrap=True)
        return None


def run(args: argparse.Namespace) -> int:
    """Validate, build, summarise, export; exit code 0, or 2 for an invalid scenario."""
    console = Console(highlight=False, soft_wrap=True)
    sc = load_or_report(args.scenario, console)
    if sc is None:
        return 2
    if args.export:
        check_file_target(args.export, "--export")
    from twin.sim.world import build_world

    world = build_world(sc)
    print_summary(sc, world.model, console)
    if args.export:
        path = world.export(args.export)
        console.print(f"exported the compiled scene to {path}")
    return 0


def print_summary(sc: Scenario, model: object, console: Console) -> None:
    """Print the space, robots, cameras (with floor views), route and calibration plan."""
    sp = sc.space
    console.print(f"[bold]{sc.name}[/bold]: {sc.description}")
    console.print(
        f"space {sp.size[0]:g} x {sp.size[1]:g} x {sp.size[2]:g} m, "
        f"x {sp.x_range[0]:g}..{sp.x_range[1]:g}, y {sp.y_range[0]:g}..{sp.y_range[1]:g}, "
        f"floor at z = {sp.floor_z:g} m; "
        f"{len(sp.obstacles)} obstacle(s), {len(sp.floor_patches)} tilted floor patch(es); "
        f"seed {sc.seed}"
    )
    console.print(
        f"MuJoCo model: {model.nbody} bodies, {model.ngeom} geoms, {model.ncam} cameras, "  # type: ignore[attr-defined]
        f"{model.nlight} lights, timestep {model.opt.timestep * 1e3:g} ms"  # type: ignore[attr-defined]
    )

    robots = Table(title="Robots")
    for col in (
        "name",
        "model",
        "start x, y (m)",
        "yaw (deg)",
        "max speed (m/s)",
        "max accel (m/s^2)",
    ):
        robots.add_column(col)
    for r in sc.robots.all:
        p = r.platform
        robots.add_row(
            r.name,
            r.model,
            f"{r.start_xy[0]:.2f}, {r.start_xy[1]:.2f}",
            f"{r.start_yaw_deg:.1f}",
            f"{p.max_speed:g}",
            f"{p.max_accel:g}",
        )
    console.print(robots)

    cams = Table(title="Cameras (floor view: where the image corners' rays meet the floor)")
    for col in (
        "name",
        "position (m)",
        "down (deg)",
        "f (px)",
        "cx, cy (px)",
        "floor view (m)",
        "area (m^2)",
    ):
        cams.add_column(col)
    for c in sc.cameras:
        cam = c.tsai()
        corners = floor_view_corners(cam, sp.floor_z)
        dist = np.linalg.norm(corners - cam.position[:2], axis=1) if len(corners) else []
        view = f"{min(dist):.1f} to {max(dist):.1f} ahead" if len(dist) else "no floor"
        cams.add_row(
            c.name,
            ", ".join(f"{v:.2f}" for v in c.position),
            f"{math.degrees(math.asin(-cam.optical_axis[2])):.1f}",
            f"{c.f:g}",
            f"{c.cx:g}, {c.cy:g}",
            view,
            f"{shapely.Polygon(corners).area if len(corners) >= 3 else 0.0:.1f}",
        )
    console.print(cams)

    turns = ", ".join(f"{t:+.0f}" for t in sc.route.turns_deg if abs(t) > 0.5) or "none"
    console.print(
        f"route: {len(sc.route.waypoints)} waypoints, {sc.route.length:.2f} m, turns (deg): {turns}"
    )
    plan = ", ".join(
        f"{v.camera} from ({v.station[0]:g}, {v.station[1]:g})" for v in sc.calibration.visits
    )
    console.print(f"calibration visits: {plan}")
