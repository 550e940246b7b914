"""``twin site``: a scenario planned from a building map and the cameras as installed."""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path
from typing import TYPE_CHECKING

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from twin.cli import arguments
from twin.outputs import check_file_target
from twin.planning.ceiling import CEILING_MARGIN, LOWEST_CEILING
from twin.scenario.limits import SMALLEST_SIZE

if TYPE_CHECKING:
    from twin.planning.repair import Attempt


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
            "montecarlo and the environment read, with a figure of the plan. The plan is "
            "run once noise-free at the geometric fidelity and, where that run drops a "
            "visit, repaired (another station, shorter legs, another visit order) until "
            "every camera is calibrated or the repairs run out. Exit code 0 when every "
            "camera is calibrated; 1 when cameras are left out (the robots cannot reach "
            "their floor views from the start) or one is not calibrated (named with why, "
            "the best plan written); 2 for a bad map, cameras file or plan (named, nothing "
            "written)."
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
        "--ceiling-height",
        type=arguments.positive_float,
        metavar="M",
        help="the ceiling's height above the floor, m (default: a mesh's own top, else the "
        f"highest camera plus {CEILING_MARGIN:g} m, at least {LOWEST_CEILING:g} m); a camera at "
        "or above it is refused by name",
    )
    p.add_argument(
        "--wall-layers",
        nargs="+",
        metavar="NAME",
        help="a DXF map's layers that hold the walls, any case (default: names holding "
        "wall, A-WALL, Wand/Wände, Mauer, mur, cloison, muro, pared, tabique, parete...)",
    )
    p.add_argument(
        "--obstacle-layers",
        nargs="+",
        metavar="NAME",
        help="a DXF map's layers that hold obstacles, any case (default: names holding "
        "obstacle, column, pillar or furniture)",
    )
    p.add_argument(
        "--speckle",
        type=speckle_area,
        metavar="M2",
        help="a ROS map's specks: blobs of occupied or unknown cells under this area with "
        "free cells all round are read as free, m^2 (default: 0.02, 8 cells at 5 cm; a post "
        "of 15 x 15 cm is kept); 0 keeps every cell",
    )
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
        help="skip the geometric run that predicts each camera's error for the figure "
        "(and the repairs)",
    )
    p.add_argument(
        "--repairs",
        type=repair_count,
        default=ATTEMPTS,
        metavar="N",
        help=f"repairs of the plan tried at most when its run drops a visit, 0 to "
        f"{MAX_REPAIRS} (default: {ATTEMPTS}; none is started after {SECONDS:g} s of "
        "repairing)",
    )
    p.add_argument("--out", type=Path, required=True, metavar="SITE.toml", help="scenario to write")
    arguments.add_overwrite(p, file=True)
    p.set_defaults(func=run)


ATTEMPTS = 6
"""Default of ``--repairs`` (:data:`twin.planning.repair.ATTEMPTS`, not imported here: the
planning modules load on use)."""
SECONDS = 120.0
"""No repair starts after this long, s (:data:`twin.planning.repair.SECONDS`)."""
MAX_REPAIRS = 100
"""Most repairs ``--repairs`` allows."""


repair_count = arguments.number_in(int, 0, MAX_REPAIRS)
"""``--repairs``: a whole number from 0 to :data:`MAX_REPAIRS`."""


MAX_RESOLUTION = 1.0
"""Coarsest grid of ``--resolution``, m: a coarser one closes doorways (the robots are half a
metre wide). The finest is the smallest obstacle a scenario holds
(:data:`twin.scenario.limits.SMALLEST_SIZE`); a grid of nanometres would not fit in memory."""


grid_resolution = arguments.number_in(float, SMALLEST_SIZE, MAX_RESOLUTION, unit="m")
"""``--resolution``: a number of metres from SMALLEST_SIZE to :data:`MAX_RESOLUTION`."""

speckle_area = arguments.number_in(float, 0.0, unit="m^2", why="an area; 0 keeps every cell")
"""``--speckle``: a finite number of m^2, at least 0."""


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
    """Plan; exit code 0, 1 when cameras are left out as out of the robots' reach or the
    plan's geometric run, repaired, does not calibrate every camera (the best plan is
    written), 2 for bad input."""
    from twin.planning.floor_map import MapError
    from twin.planning.site import STATION_NEED
    from twin.planning.site_file import write_site

    console = Console(highlight=False, soft_wrap=True)
    # The scenario and its figure beside it, checked before the plan is made.
    check_file_target(args.out, "--out")
    check_file_target(args.out.with_suffix(".plan.png"), "--out's figure")
    map_options = {
        key: value
        for key, value in (
            ("wall_layers", args.wall_layers),
            ("obstacle_layers", args.obstacle_layers),
            ("speckle", args.speckle),
        )
        if value is not None
    }
    if args.speckle is not None and args.map.suffix.lower() not in (".yaml", ".yml"):
        console.print(
            f"[red]error:[/red] --speckle: a ROS map's (map.yaml) cells; "
            f"{escape(str(args.map))} is not a .yaml file"
        )
        return 2
    layers = {k: v for k, v in map_options.items() if k != "speckle"}
    if layers and args.map.suffix.lower() != ".dxf":
        option = "--wall-layers" if args.wall_layers is not None else "--obstacle-layers"
        console.print(
            f"[red]error:[/red] {option}: a DXF map's layers; {escape(str(args.map))} is "
            "not a .dxf file"
        )
        return 2
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
            repairs=args.repairs,
            repair_seconds=SECONDS,
            tried=lambda attempt: print_attempt(attempt, console),
            ceiling_height=args.ceiling_height,
            map_options=map_options,
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
    for note in plan.floor.notes:
        if "speckle =" in note:
            console.print(f"map: {escape(note)}")
    console.print(f"scenario: {written.path}; figure: {written.figure}")
    for cam, how in plan.moved.items():
        console.print(f"[yellow]warning:[/yellow] camera {cam!r} {escape(how)}")
    left_out = (
        (
            plan.unreachable,
            "the robots cannot reach these cameras' floor views from the start (left out of "
            "the plan; the map's frame, m)",
            " ",
        ),
        (
            plan.hidden,
            "no station sees enough of these cameras' floor views (left out of the plan)",
            ": ",
        ),
    )
    code = 0
    for cameras, title, sep in left_out:
        if cameras:
            console.print(f"[yellow]warning:[/yellow] {title}:")
            for cam, why in cameras.items():
                console.print(f"  {cam}{sep}{escape(why)}")
            code = 1
    for cam, seen in plan.partial.items():
        console.print(
            f"note: camera {cam!r}: its station sees {100 * seen:.0f} % of its floor view "
            f"(no station sees {100 * STATION_NEED:.0f} %); the scenario's "
            "calibration.min_visible_fraction is "
            f"{plan.scenario['calibration']['min_visible_fraction']:g}"
        )
    kept = sum(a.kept for a in written.repairs)
    if written.repairs:
        console.print(f"{len(written.repairs)} repairs tried, {kept} kept")
    if written.not_calibrated:
        how = (
            f"after {len(written.repairs)} repairs"
            if written.repairs
            else "and no repair was tried"
            if args.repairs == 0 or args.no_predict
            else "and no repair applies"
        )
        console.print(
            "[yellow]warning:[/yellow] the plan's geometric run does not calibrate every "
            f"camera {how} (the best plan is written, to be looked at and edited):"
        )
        for cam, why in written.not_calibrated.items():
            console.print(f"  {cam}: {escape(why)}")
        return 1
    if kept:
        console.print("every camera of the plan is calibrated by the repaired plan")
    return code


def print_attempt(attempt: Attempt, console: Console) -> None:
    """One repair as it ends: what it did and what its run gave."""
    if attempt.run is None:
        result = f"[red]no plan[/red]: {escape(attempt.error)}"
    else:
        run = attempt.run
        result = f"{len(run.calibrated)} cameras calibrated, {len(run.dropped)} visits dropped"
        result += "; [green]kept[/green]" if attempt.kept else "; not better, undone"
    console.print(f"{escape(attempt.cause)} dropped; repair: {escape(attempt.what)}: {result}")
