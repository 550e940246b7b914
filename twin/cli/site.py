"""``twin site``: a scenario planned from a building map and the cameras as installed."""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from twin.cli import arguments
from twin.outputs import check_file_target
from twin.scenario.limits import SMALLEST_SIZE


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``site`` subcommand."""
    p = sub.add_parser(
        "site",
        help="plan a campaign from a building map: stations, visit order, route",
        description=(
            "Read a map (a ROS occupancy grid map.yaml, a DXF floor plan, or a building "
            "mesh: OBJ, STL, PLY, glTF) and the cameras as installed (a YAML list or TOML "
            "[[cameras]] with a scenario camera's keys, in the map's frame; position z is "
            "the height above the floor), choose each camera's station, the shortest tour "
            "over them and the route between, and write a scenario that twin run, twin "
            "montecarlo and the environment read, with a figure of the plan. Exit code 0; "
            "2 for a bad map, cameras file or plan (named, nothing written)."
        ),
    )
    p.add_argument("map", type=Path, help="map.yaml, a .dxf, or a mesh (.obj .stl .ply .gltf .glb)")
    p.add_argument("--cameras", type=Path, required=True, help="cameras file (.yaml or .toml)")
    p.add_argument(
        "--start",
        type=arguments.finite_float,
        nargs=3,
        metavar=("X", "Y", "YAW_DEG"),
        help="the parent's start in the map, m and degrees (default: chosen)",
    )
    p.add_argument(
        "--visits",
        type=visit_order,
        metavar="CAM,CAM,...",
        help="cameras in the order to calibrate them, comma-separated; a camera may come "
        "twice, e.g. cam1,cam2,cam3,cam2,cam1 (default: each once, shortest tour)",
    )
    p.add_argument("--return-to-start", action="store_true", help="end the route back at the start")
    p.add_argument(
        "--resolution",
        type=grid_resolution,
        default=0.1,
        metavar="M",
        help=f"grid the map's blocked floor is laid on as boxes, {SMALLEST_SIZE:g} to "
        f"{MAX_RESOLUTION:g} m (default: 0.1)",
    )
    p.add_argument(
        "--data-stops",
        choices=("all_leds", "accuracy"),
        default="all_leds",
        help="the scenario's campaign.data_stops: all_leds (the default; the default planned "
        "strategy chooses the stops for accuracy all the same, the paper strategy where all "
        "the child's LEDs show) or accuracy (stops chosen to lower the camera's predicted "
        "error under any strategy)",
    )
    p.add_argument("--name", help="the scenario's name (default: the output file's stem)")
    p.add_argument(
        "--no-predict",
        action="store_true",
        help="skip the geometric run that predicts each camera's error for the figure",
    )
    p.add_argument("--out", type=Path, required=True, metavar="SITE.toml", help="scenario to write")
    arguments.add_overwrite(p, file=True)
    p.set_defaults(func=run)


MAX_RESOLUTION = 1.0
"""Coarsest grid of ``--resolution``, m: a coarser one closes doorways (the robots are half a
metre wide). The finest is the smallest obstacle a scenario holds
(:data:`twin.scenario.limits.SMALLEST_SIZE`); a grid of nanometres would not fit in memory."""


def grid_resolution(text: str) -> float:
    """``--resolution``: a number of metres from SMALLEST_SIZE to :data:`MAX_RESOLUTION`."""
    value = arguments.finite_float(text)
    if not SMALLEST_SIZE <= value <= MAX_RESOLUTION:
        raise argparse.ArgumentTypeError(
            f"expected {SMALLEST_SIZE:g} to {MAX_RESOLUTION:g} m, got {text}"
        )
    return value


def visit_order(text: str) -> list[str]:
    """The cameras of ``--visits``, comma-separated (blanks around a name and empty entries,
    as from a trailing comma, are left out).

    Raises:
        argparse.ArgumentTypeError: no camera named.
    """
    names = [name.strip() for name in text.split(",")]
    names = [name for name in names if name]
    if not names:
        raise argparse.ArgumentTypeError(
            f"expected camera names separated by commas, e.g. cam1,cam2,cam1; got {text!r}"
        )
    return names


def run(args: argparse.Namespace) -> int:
    """Plan; exit code 0, 1 when one geometric run of the plan does not calibrate every
    camera (the plan is written), 2 for bad input."""
    from twin.planning.floor_map import MapError
    from twin.planning.site_file import write_site

    console = Console(highlight=False, soft_wrap=True)
    # The scenario and its figure beside it, checked before the plan is made.
    check_file_target(args.out, "--out")
    check_file_target(args.out.with_suffix(".plan.png"), "--out's figure")
    start = None
    if args.start is not None:
        x, y, yaw = args.start
        start = (x, y, math.radians(yaw))
    visits = args.visits
    t0 = time.perf_counter()
    try:
        written = write_site(
            args.map,
            args.cameras,
            args.out,
            name=args.name,
            start=start,
            visits=visits,
            return_to_start=args.return_to_start,
            resolution=args.resolution,
            predict=not args.no_predict,
            overwrite=args.overwrite,
            data_stops=args.data_stops,
        )
    except (MapError, ValueError) as exc:
        console.print(f"[red]error:[/red] {escape(str(exc))}")
        return 2
    plan = written.plan
    table = Table(title=f"{written.scenario.name}: planned in {time.perf_counter() - t0:.1f} s")
    for col in ("visit", "camera", "station x [m]", "station y [m]", "sees [%]", "predicted [mm]"):
        table.add_column(col, justify="right")
    for k, cam in enumerate(plan.order):
        st = plan.stations[cam]
        pred = written.predicted_mm.get(cam)
        table.add_row(
            str(k + 1),
            cam,
            f"{st.xy[0]:.2f}",
            f"{st.xy[1]:.2f}",
            f"{100 * st.visible:.0f}",
            "-" if pred is None else f"{pred:.1f}",
        )
    console.print(table)
    console.print(
        f"route {written.route_length_m:.1f} m, {len(plan.space.boxes)} boxes at a "
        f"{plan.space.resolution:g} m grid; W is the map's ({plan.pose.x:.2f}, "
        f"{plan.pose.y:.2f}) heading {math.degrees(plan.pose.yaw):.1f} deg"
    )
    console.print(f"scenario: {written.path}; figure: {written.figure}")
    if written.not_calibrated:
        console.print(
            "[yellow]warning:[/yellow] one geometric run of the plan does not calibrate "
            "every camera (the plan is written, to be looked at and edited):"
        )
        for cam, why in written.not_calibrated.items():
            console.print(f"  {cam}: {escape(why)}")
        return 1
    return 0
