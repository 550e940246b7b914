"""A campaign planned on a map: the scenario ``twin site`` writes.

From a floor map (:mod:`twin.planning.maps`) and the cameras as installed (their
approximate poses and nominal intrinsics, in the map's frame), the planner:

1. keeps to the floor the parent reaches from its start (:mod:`twin.planning.regions`:
   the cameras whose floor view lies elsewhere are left out, named with why) and takes
   the start (given, or before the first station where the group fits, heading along the
   map's x-axis) as the world frame W;
2. lays the map's blocked floor as boxes in W (:mod:`twin.planning.boxes`), which the
   scenario does not write out: it references the map (``[space.map]``) and its hash;
3. chooses each camera's station (:mod:`twin.planning.stations`);
4. orders the visits by the shortest tour over the stations (:mod:`twin.planning.tour`)
   unless the user gives the order, with a return to the start if asked;
5. routes the parent between them by shortest paths with the CPS formation's clearance
   (:mod:`twin.planning.route`);
6. places the children beside the start.

The result is an ordinary scenario (a mapping, validated by the scenario loader) with a
``[site]`` section that keeps the map and the map-to-W transform.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import shapely
import yaml
from numpy.typing import NDArray
from shapely.geometry import LineString, Point, Polygon
from shapely.geometry.base import BaseGeometry
from shapely.ops import nearest_points

from calib.camera import TsaiCamera
from calib.io.text import read_text, yaml_load
from twin.campaign.plan.accurate_stops import partial_view_stops
from twin.planning.boxes import DEFAULT_RESOLUTION, BoxedSpace, boxed_space
from twin.planning.ceiling import check_ceiling, site_ceiling
from twin.planning.floor_map import FloorMap, MapError
from twin.planning.frames import MapPose
from twin.planning.map_files import map_sha256
from twin.planning.regions import (
    CHILD_CLEARANCE,
    children_at,
    floor_pieces,
    group_start,
    main_piece,
    piece_at,
    unreachable_why,
    view_counts,
)
from twin.planning.route import TOLERANCE, NoPathError, RouteGraph
from twin.planning.stations import NoStationError, Station, choose_station
from twin.planning.tour import order_visits
from twin.scenario.cross_checks import PARENT_CLEARANCE
from twin.scenario.errors import ScenarioError
from twin.scenario.geometry import floor_view, inside_obstacles
from twin.scenario.loader import validate_model
from twin.scenario.map_space import map_obstacle
from twin.scenario.robots import INSTRUMENT_HEIGHT, PIONEER3AT
from twin.scenario.schema import CameraConfig, MarkerConfig, Noise, Space

FORMATION_CLEARANCE = PIONEER3AT.radius + 0.35
"""Clearance the parent's route keeps from everything, m: the parent's radius and room
for a child beside it in the CPS formation's turns."""

STATION_CLEARANCE = 1.5
"""Clearance a station keeps from everything, m: the children stand beside and ahead of
the parent there (the formation's sideways offset, a child's radius, and a margin); where
no floor is that wide, a station keeps the route's clearance."""

ROUTE_CLEARANCES = (STATION_CLEARANCE, 1.25, 1.0, 0.85)
"""Clearances the route tries, widest first, m: where the start stands 1 m from a wall, say,
a route 1.5 m clear cannot leave it, and one 1 m clear still keeps the formation's lines of
sight off the corners that one at the parent's own clearance grazes."""

PASSAGE_CLEARANCE = PIONEER3AT.radius + 0.1
"""Clearance the route keeps in a passage (a doorway) too narrow for the formation's, m:
the parent's radius and a margin (a door 0.9 m wide and more). Only where no wider
clearance joins the start and every station."""

STATION_NEED = 0.5
"""Least fraction of a camera's floor view a station must see (the scenario's default
``calibration.min_visible_fraction``)."""

STATION_FLOOR = 0.25
"""Least fraction a station may see where none sees :data:`STATION_NEED` (shelves or a
wall across the camera's view): a quarter of the view still holds the station's data set
spread over half the view's width and depth, which a calibration needs; the plan then
lowers the scenario's ``calibration.min_visible_fraction`` to what its stations see. A
camera no station sees this much of is left out of the plan, named."""

START_PRISM_DISTANCES = (1.5, 2.0, 1.0, 2.5)
"""How far from the start a prism left there stands, m, in the order tried."""
START_PRISM_TURNS_DEG = (0.0, 30.0, -30.0, 60.0, -60.0, 90.0, -90.0, 120.0, -120.0)
"""Its direction from the start, degrees from straight behind the route's first leg."""
START_PRISM_CLEARANCE = 0.3
"""The prism's pole stands this far from walls and obstacles at least, m."""
START_PRISM_OFF_ROUTE = 0.8
"""And this far from the route and from the children's starts at least, m."""
START_PRISM_SIGHT = 8.0
"""The parent measures it from every station this close, m."""

CAMERA_KEYS = (
    "name",
    "position",
    "view_direction",
    "f",
    "cx",
    "cy",
    "kappa1",
    "sx",
    "image_size",
    "opencv_distortion",
    "sensor",
    "led_centroid_px",
)


@dataclass(frozen=True)
class SitePlan:
    """A planned campaign on a map.

    Attributes:
        scenario: the scenario as a mapping (TOML-ready).
        pose: W in the map's frame.
        space: the room and its boxes in W.
        stations: each camera's station, by camera name.
        order: the visits' cameras, in order.
        route: (K, 2) the parent's route in W, m.
        floor: the map (with the plan's ceiling).
        unreachable: the cameras left out, each with where it is and why the robots cannot
            reach its floor view from the start (map frame).
        hidden: the cameras left out because no station sees :data:`STATION_FLOOR` of
            their floor view, each with the best found and where (W).
        partial: by camera name, the fraction its station sees where it is under
            :data:`STATION_NEED` (the scenario accepts it: see :data:`STATION_FLOOR`).
    """

    scenario: dict[str, Any]
    pose: MapPose
    space: BoxedSpace
    stations: dict[str, Station]
    order: tuple[str, ...]
    route: NDArray[np.float64]
    floor: FloorMap
    unreachable: dict[str, str] = dataclasses.field(default_factory=dict)
    hidden: dict[str, str] = dataclasses.field(default_factory=dict)
    partial: dict[str, float] = dataclasses.field(default_factory=dict)


def read_cameras(path: str | Path) -> list[dict[str, Any]]:
    """The cameras file: a YAML list (or mapping with ``cameras``), or TOML
    ``[[cameras]]``, each with a scenario camera's keys, in the map's frame (``position``'s
    z is the height above the floor, m).

    Raises:
        MapError: the file cannot be read, or a camera is not a table of known keys, or
            one of its values is not a scenario camera's (a NaN focal length, say); the
            message names the camera (its index and name) and the key.
    """
    path = Path(path)
    try:
        text = read_text(path)
        raw: Any = tomllib.loads(text) if path.suffix == ".toml" else yaml_load(text)
    except (OSError, ValueError, yaml.YAMLError) as exc:
        raise MapError(path, f"cannot read the cameras: {exc}") from None
    if isinstance(raw, Mapping):
        raw = raw.get("cameras")
    if not isinstance(raw, list) or not raw:
        raise MapError(path, "expected a list of cameras (YAML list, or TOML [[cameras]])")
    out = []
    for k, cam in enumerate(raw):
        where = f"camera {k}" + (f" ({cam.get('name')!r})" if isinstance(cam, Mapping) else "")
        if not isinstance(cam, Mapping):
            raise MapError(path, f"{where}: expected a table of camera keys, got {cam!r}")
        unknown = sorted(set(cam) - set(CAMERA_KEYS))
        if unknown:
            raise MapError(path, f"{where}: unknown keys {unknown}; expected {CAMERA_KEYS}")
        for key in ("name", "position", "view_direction", "f", "cx", "cy", "image_size"):
            if key not in cam:
                raise MapError(path, f"{where}: the key {key!r} is missing")
        position = cam["position"]
        if not (
            isinstance(position, list)
            and len(position) == 3
            and all(_finite_number(v) for v in position)
        ):
            raise MapError(
                path,
                f"{where}: position: expected 3 finite numbers (x, y in the map's frame and "
                f"the height above the floor, m), got {position!r}",
            )
        try:
            # The position is the map's (any size: the map's own coordinates); the rest is
            # checked as a scenario camera's.
            validate_model(CameraConfig, {**cam, "position": [0.0, 0.0, position[2]]}, path)
        except ScenarioError as exc:
            problems = "; ".join(str(issue) for issue in exc.issues)
            raise MapError(path, f"{where}: {problems}") from None
        out.append(dict(cam))
    return out


def _finite_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def plan_site(
    floor: FloorMap,
    cameras: Sequence[Mapping[str, Any]],
    *,
    name: str = "site",
    start: tuple[float, float, float] | None = None,
    visits: Sequence[str] | None = None,
    return_to_start: bool = False,
    resolution: float = DEFAULT_RESOLUTION,
    map_file: str = "",
    seed: int = 1,
    avoid: Mapping[str, Sequence[Sequence[float]]] | None = None,
    ceiling_height: float | None = None,
) -> SitePlan:
    """Plan the campaign of ``cameras`` on ``floor`` (see the module).

    Args:
        floor: the map. cameras: the cameras file's entries, map frame.
        name: the scenario's name. start: (x m, y m, yaw rad) of the parent's start in the
            map (default: chosen). visits: the cameras in the order to calibrate them (a
            camera may come twice, as in the paper's 1-2-3-2-1); default: each camera once,
            in the shortest tour's order. return_to_start: end the route at the start, and
            leave a prism near it (a control point) that closes the loop in the global
            adjustment (none if no place near the start is clear).
        resolution: the boxes' grid, m. map_file: the map's path as the scenario keeps it.
        seed: the scenario's seed.
        avoid: by camera name, (x, y) places in the map's frame, m, that the camera's
            station keeps :data:`twin.planning.stations.AVOID_RADIUS` from (where a run of an
            earlier plan failed: :mod:`twin.planning.repair`); default none.
        ceiling_height: the ceiling above the floor, m
            (default: :func:`twin.planning.ceiling.site_ceiling`).

    Returns:
        The plan of the cameras the robots can reach from the start; the others are in
        :attr:`SitePlan.unreachable`, each with why (:mod:`twin.planning.regions`).

    Raises:
        MapError: a camera outside the map or at or above the ceiling, no station for a
            camera, no path between two stations, a start off the floor or without room for
            the children, no camera reachable; the message names it, in the map's frame.
    """
    names = [str(c["name"]) for c in cameras]
    if len(set(names)) != len(names):
        raise MapError(floor.source, f"camera names repeat: {names}")
    for cam in cameras:
        xy = np.asarray(cam["position"], dtype=float)[:2]
        x0, y0, x1, y1 = floor.bounds
        if not (x0 <= xy[0] <= x1 and y0 <= xy[1] <= y1):
            raise MapError(
                floor.source,
                f"camera {cam['name']!r} at {xy.tolist()} lies outside the map "
                f"(x {x0:.2f} to {x1:.2f}, y {y0:.2f} to {y1:.2f} m)",
            )
    wanted = list(visits) if visits is not None else None
    if wanted is not None:
        unknown = sorted(set(wanted) - set(names))
        if unknown:
            raise MapError(floor.source, f"visits name unknown cameras {unknown}; known {names}")
    ceiling = site_ceiling(floor, cameras, ceiling_height)
    check_ceiling(floor, cameras, ceiling, given=ceiling_height is not None)
    floor = dataclasses.replace(floor, height=ceiling)
    parent_free = floor.reachable(FORMATION_CLEARANCE)
    if parent_free.is_empty:
        raise MapError(floor.source, "no floor is wide enough for the robots")
    floor_z = -INSTRUMENT_HEIGHT
    # The pieces of floor are those the parent passes between (a doorway joins two rooms);
    # it drives and stands with the formation's clearance wherever the floor allows.
    passable, unreachable = _region(
        floor, cameras, floor.reachable(PASSAGE_CLEARANCE), parent_free, start, floor_z
    )
    parent_free = parent_free.intersection(passable)
    cameras = [c for c in cameras if str(c["name"]) not in unreachable]
    names = [str(c["name"]) for c in cameras]
    if wanted is not None:
        wanted = [c for c in wanted if c not in unreachable]
        if not wanted:
            listing = "; ".join(f"{k} {v}" for k, v in unreachable.items())
            raise MapError(
                floor.source, f"the robots can reach no camera of the visits given: {listing}"
            )
    station_free = (floor.reachable(STATION_CLEARANCE).intersection(parent_free), parent_free)
    chosen = list(dict.fromkeys(wanted if wanted is not None else names))
    if start is None:
        # Stations first, in the map's frame; then the start just before the first of the
        # best open tour over them, so that the route runs on rather than back and forth.
        in_map, hidden = _stations(
            floor, cameras, chosen, MapPose(), station_free, floor_z, resolution, avoid
        )
        cameras, names, wanted = _without(floor, hidden, cameras, wanted, unreachable)
        graph = RouteGraph(passable)
        first, second = _first_two(graph, in_map, wanted, floor.source)
        pose = MapPose(*_group_start(floor, parent_free, _lead_in(first, second, parent_free)), 0.0)
        stations = {
            k: dataclasses.replace(
                st, xy=pose.map2world(st.xy), view_centre=pose.map2world(st.view_centre)
            )
            for k, st in in_map.items()
        }
    else:
        x, y, yaw = (float(v) for v in start)
        pose = MapPose(x, y, yaw)
        stations, hidden = _stations(
            floor, cameras, chosen, pose, station_free, floor_z, resolution, avoid
        )
        cameras, names, wanted = _without(floor, hidden, cameras, wanted, unreachable)
    partial = {c: st.visible for c, st in stations.items() if st.visible < STATION_NEED}
    boxed = boxed_space(floor, pose, resolution)
    if start is None:  # the boxes laid in the chosen W: checked again
        space = _space(boxed, floor_z)
        _check_cameras_clear(floor, cameras, pose, boxed, space, floor_z)
    cams_w = {c["name"]: _camera_in_world(c, pose, floor_z) for c in cameras}
    reach_w = pose.geometry2world(parent_free)
    graph = _clear_of_boxes(_route_graph(floor, pose, reach_w, stations), boxed)
    points = [np.zeros(2), *(stations[c].xy for c in stations)]
    keys = list(stations)
    try:
        dist = graph.lengths(points)
    except NoPathError as exc:
        raise MapError(floor.source, f"no free path between two stations: {exc}") from None
    if wanted is None:
        order = order_visits(dist, len(points), start=0, return_to_start=return_to_start)
        sequence = [keys[i - 1] for i in order if i != 0]
    else:
        sequence = wanted
    route, arrivals = _route(graph, [stations[c].xy for c in sequence], return_to_start)
    if not return_to_start:
        route = _run_out(route, reach_w)
    children = _children(floor, pose)
    prism = _start_prism(floor, pose, route, children) if return_to_start else None
    scenario = _scenario(
        name=name,
        seed=seed,
        space=boxed,
        map_ref=_map_ref(floor, map_file or floor.source, pose, resolution),
        floor_z=floor_z,
        cameras=[cams_w[n] for n in names],
        children=children,
        route=route,
        return_to_start=return_to_start,
        start_prism=prism,
        visits=[
            (cam, stations[cam].xy, heading)
            for cam, heading in zip(sequence, arrivals, strict=True)
        ],
        min_visible=_min_visible(partial),
        site={
            "map": map_file or floor.source,
            "map_pose": [pose.x, pose.y, math.degrees(pose.yaw)],
            "resolution": resolution,
        },
    )
    return SitePlan(
        scenario,
        pose,
        boxed,
        stations,
        tuple(sequence),
        route,
        floor,
        unreachable,
        hidden,
        partial,
    )


def _without(
    floor: FloorMap,
    hidden: Mapping[str, str],
    cameras: Sequence[Mapping[str, Any]],
    wanted: Sequence[str] | None,
    unreachable: Mapping[str, str],
) -> tuple[list[Mapping[str, Any]], list[str], list[str] | None]:
    """The cameras, their names and the visits given (None: none given) without the
    ``hidden`` ones (no station sees enough of them).

    Raises:
        MapError: no camera is left, naming each left out and why.
    """
    cameras = [c for c in cameras if str(c["name"]) not in hidden]
    if not cameras or (wanted is not None and not set(wanted) - set(hidden)):
        listing = "; ".join(f"{k}: {v}" for k, v in {**unreachable, **hidden}.items())
        raise MapError(floor.source, f"no station for any camera of the plan: {listing}")
    names = [str(c["name"]) for c in cameras]
    return cameras, names, None if wanted is None else [c for c in wanted if c not in hidden]


def _min_visible(partial: Mapping[str, float]) -> float:
    """The scenario's ``calibration.min_visible_fraction``: :data:`STATION_NEED`, or where
    a station sees less (``partial``: by camera, the fraction), a percent under the least
    of those, to the percent below (the scenario's check computes the fraction again, in
    the boxes laid in W)."""
    if not partial:
        return STATION_NEED
    return max(STATION_FLOOR - 0.01, math.floor(100 * min(partial.values())) / 100 - 0.01)


def _route_graph(
    floor: FloorMap, pose: MapPose, reachable: BaseGeometry, stations: Mapping[str, Station]
) -> RouteGraph:
    """The graph the route is planned on: the floor shrunk by the widest of
    :data:`ROUTE_CLEARANCES` that holds the start and every station in one piece (the
    route keeps to the middle of corridors, where the instrument sees the children around
    a corner, and clear of the corners it turns round), then the parent's own clearance,
    then the widest down to :data:`PASSAGE_CLEARANCE` (through a doorway: the route passes
    its middle), else every floor the parent can reach."""
    for clearance in (*ROUTE_CLEARANCES, FORMATION_CLEARANCE):
        roomy = pose.geometry2world(floor.reachable(clearance))
        if roomy.is_empty:
            continue
        graph = RouteGraph(roomy)
        regions = {graph.region_of(np.zeros(2))}
        regions |= {graph.region_of(st.xy) for st in stations.values()}
        if len(regions) == 1 and None not in regions:
            return graph
    points = [Point(0.0, 0.0), *(Point(*st.xy) for st in stations.values())]
    passage = _widest_joining(floor, pose, points, PASSAGE_CLEARANCE, FORMATION_CLEARANCE)
    if passage is None:
        _check_passages(floor, pose, points)
        return RouteGraph(reachable)
    return RouteGraph(pose.geometry2world(floor.reachable(passage)))


BOX_MARGIN = PARENT_CLEARANCE + 1e-6
"""The route keeps this far from the boxes, m, the way the scenario's loader checks it: each
box grown by the parent's radius on every side, still a rectangle (not rounded at its
corners), its boundary included."""


def _clear_of_boxes(graph: RouteGraph, boxed: BoxedSpace) -> RouteGraph:
    """``graph`` kept off the boxes grown by :data:`BOX_MARGIN`, as the loader checks the
    route. The route keeps its clearance from the map (round, about corners); the boxes are
    the map laid on a coarser grid (a corner up to half a cell further out) and grown
    square, so a route that passes a speck or a wall's corner at the passage clearance can
    run within the loader's margin of a box's corner. Returns ``graph`` itself where no
    grown box reaches its floor."""
    grown = [
        shapely.box(
            b.center[0] - 0.5 * b.size[0] - BOX_MARGIN,
            b.center[1] - 0.5 * b.size[1] - BOX_MARGIN,
            b.center[0] + 0.5 * b.size[0] + BOX_MARGIN,
            b.center[1] + 0.5 * b.size[1] + BOX_MARGIN,
        )
        for b in boxed.boxes
    ]
    if not grown:
        return graph
    keep_out = shapely.union_all(grown)
    if not graph.reachable.intersects(keep_out):
        return graph
    return RouteGraph(graph.reachable.difference(keep_out))


def _check_passages(floor: FloorMap, pose: MapPose, points: Sequence[Point]) -> None:
    """Where the free floor joins ``points`` (W) but only through a passage narrower than
    the parent passes (:data:`PASSAGE_CLEARANCE` on either side), name the passage.

    Raises:
        MapError: naming where the passage is, in the map's frame, and the width needed.
    """
    free = pose.geometry2world(floor.free)
    if not any(all(p.covers(q) for q in points) for p in getattr(free, "geoms", [free])):
        return  # pieces of floor no passage joins: the route says so
    roomy = pose.geometry2world(floor.reachable(PASSAGE_CLEARANCE))
    pieces = list(getattr(roomy, "geoms", [roomy]))
    start = next((p for p in pieces if p.covers(points[0])), None)
    cut = next((q for q in points[1:] if start is None or not start.covers(q)), points[0])
    other = next((p for p in pieces if p.covers(cut)), None)
    if start is None or other is None:
        return
    a, b = nearest_points(start, other)
    x, y = pose.world2map([0.5 * (a.x + b.x), 0.5 * (a.y + b.y)])
    raise MapError(
        floor.source,
        f"the passage near ({x:.2f}, {y:.2f}) (the map's frame, m) is narrower than the "
        f"parent needs ({2 * PASSAGE_CLEARANCE:.2f} m: its width and a margin on either "
        "side): the stations beyond it cannot be reached",
    )


PASSAGE_SLACK = 0.02
"""A route through a passage keeps this much less than the widest clearance that passes
it, m (at that clearance the passage is a line)."""


def _widest_joining(
    floor: FloorMap, pose: MapPose, points: Sequence[Point], least: float, most: float
) -> float | None:
    """The widest clearance from ``least`` to ``most`` (m, to a centimetre, less
    :data:`PASSAGE_SLACK`) at which the floor holds ``points`` (W) in one piece; None
    where even ``least`` does not."""

    def joins(clearance: float) -> bool:
        roomy = pose.geometry2world(floor.reachable(clearance))
        pieces = getattr(roomy, "geoms", [roomy])
        return any(all(piece.covers(p) for p in points) for piece in pieces)

    if not joins(least):
        return None
    lo, hi = least, most
    while hi - lo > 0.01:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if joins(mid) else (lo, mid)
    return max(least, lo - PASSAGE_SLACK)


def _stations(
    floor: FloorMap,
    cameras: Sequence[Mapping[str, Any]],
    chosen: Sequence[str],
    pose: MapPose,
    station_free: tuple[BaseGeometry, BaseGeometry],
    floor_z: float,
    resolution: float,
    avoid: Mapping[str, Sequence[Sequence[float]]] | None = None,
) -> tuple[dict[str, Station], dict[str, str]]:
    """Each chosen camera's station in the frame ``pose`` makes W: on the roomy floor
    (``station_free[0]``) where one there sees :data:`STATION_NEED`, else on the floor the
    parent can reach (``station_free[1]``), else the one that sees the most of the two
    where it sees :data:`STATION_FLOOR`; away from the camera's places in ``avoid`` (map
    frame). Returns the stations by camera name, and the cameras with none, each with
    why (the best fraction found and where)."""
    boxed = boxed_space(floor, pose, resolution)
    space = _space(boxed, floor_z)
    _check_cameras_clear(floor, cameras, pose, boxed, space, floor_z)
    by_name = {str(c["name"]): c for c in cameras}
    marker = MarkerConfig()
    ts = Noise().total_station
    wheres = [pose.geometry2world(g) for g in station_free if not g.is_empty]
    out: dict[str, Station] = {}
    hidden: dict[str, str] = {}
    assembly = marker.assembly()
    instrument_range = (ts.range_min, ts.range_max)
    for name in chosen:
        camera = validate_model(CameraConfig, _camera_in_world(by_name[name], pose, floor_z)).tsai()
        found: list[Station] = []
        best: Station | None = None
        why = "no place the robots reach near its floor view"

        def gives_data(xy: NDArray[np.float64], camera: TsaiCamera = camera) -> bool:
            # The campaign's own planner of data stops, from the station (no anchor yet).
            return bool(
                partial_view_stops(
                    space, assembly, instrument_range, camera, xy, floor_z + INSTRUMENT_HEIGHT, None
                )
            )

        # The roomy floor first, then all the parent reaches; where no station sees
        # STATION_NEED, the best of those that see STATION_FLOOR.
        for need in (STATION_NEED, STATION_FLOOR):
            for where in wheres:
                try:
                    found.append(
                        choose_station(
                            name,
                            camera,
                            space,
                            where,
                            instrument_z=floor_z + INSTRUMENT_HEIGHT,
                            prism_height=float(np.mean([c[2] for c in marker.cubes])),
                            instrument_range=(ts.range_min, ts.range_max),
                            need=need,
                            avoid=_avoided(avoid, name, pose),
                            gives_data=gives_data,
                        )
                    )
                    if need == STATION_NEED:
                        break
                except NoStationError as exc:
                    if exc.best is None:
                        why = str(exc)
                    elif best is None or exc.best.visible > best.visible:
                        best = exc.best
            if found:
                break
        if found:
            out[name] = max(found, key=lambda st: st.visible)
        elif best is None:
            hidden[name] = why
        else:
            x, y = pose.world2map(best.xy)
            hidden[name] = (
                f"no station sees {100 * STATION_FLOOR:.0f} % of its floor view (walls or "
                f"obstacles hide it): at best {100 * best.visible:.0f} % from ({x:.2f}, "
                f"{y:.2f}); is the camera placed and aimed as in the map's frame?"
            )
    return out, hidden


def _avoided(
    avoid: Mapping[str, Sequence[Sequence[float]]] | None, name: str, pose: MapPose
) -> NDArray[np.float64] | None:
    """(K, 2) the places camera ``name``'s station avoids, in the W of ``pose``; None if
    none."""
    places = (avoid or {}).get(name)
    if not places:
        return None
    return pose.map2world(np.asarray(places, dtype=float).reshape(-1, 2))


def _check_cameras_clear(
    floor: FloorMap,
    cameras: Sequence[Mapping[str, Any]],
    pose: MapPose,
    boxed: BoxedSpace,
    space: Space,
    floor_z: float,
) -> None:
    """Refuse a camera that stands inside one of the boxes the map's blocked floor is laid
    as, below its top (the scenario would refuse it), in the terms of the cameras file:
    the camera's name, where it stands in the map's frame and what of the map it stands in.

    Raises:
        MapError: naming the camera and the obstacle, map frame.
    """
    obstacles = space.obstacles
    if not obstacles:
        return
    tops = np.array([floor_z + ob.size[2] for ob in obstacles])
    for cam in cameras:
        p = np.asarray(cam["position"], dtype=float)
        inside = inside_obstacles(obstacles, [pose.map2world(p[:2])])[:, 0]
        hit = np.flatnonzero(inside & (floor_z + p[2] < tops))
        if not hit.size:
            continue
        mapped = [ob for ob in floor.obstacles if ob.footprint.covers(Point(p[:2]))]
        if mapped:
            ob = mapped[0]
            x0, y0, x1, y1 = ob.footprint.bounds
            high = "up to the ceiling" if math.isinf(ob.height) else f"{ob.height:.2f} m high"
            what = f"the map's obstacle {ob.name!r}"
        else:  # a wall or floor the map does not show free, as its box laid on the grid
            box = boxed.boxes[hit[0]]
            half = 0.5 * np.asarray(box.size)
            square = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]])
            corners = pose.world2map(np.asarray(box.center) + half * square)
            (x0, y0), (x1, y1) = corners.min(axis=0), corners.max(axis=0)
            high = f"{box.height:.2f} m high"
            what = "the map's blocked floor"
        raise MapError(
            floor.source,
            f"camera {cam['name']!r} at ({p[0]:.2f}, {p[1]:.2f}), {p[2]:.2f} m above the "
            f"floor, stands inside {what} (x {x0:.2f} to {x1:.2f}, y {y0:.2f} to {y1:.2f}, "
            f"{high}; the map's frame, m); expected a camera over free floor or above what "
            "stands there",
        )


def _first_two(
    graph: RouteGraph,
    stations: Mapping[str, Station],
    wanted: Sequence[str] | None,
    source: str,
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    """The first two stations of the visits (given, or the best open tour's from any
    start), map frame."""
    keys = list(stations)
    if wanted is not None:
        order = list(dict.fromkeys(wanted))
    elif len(keys) == 1:
        order = keys
    else:
        points = [stations[k].xy for k in keys]
        try:
            between = graph.lengths(points)
        except NoPathError as exc:
            raise MapError(source, f"no free path between two stations: {exc}") from None
        # A node at no distance from every station: the best open tour from it starts
        # wherever the best open path over the stations does.
        n = len(points) + 1
        dist = np.zeros((n, n))
        dist[1:, 1:] = between
        order = [keys[i - 1] for i in order_visits(dist, n, start=0) if i != 0]
    first = stations[order[0]].xy
    second = stations[order[1]].xy if len(order) > 1 else None
    return first, second


LEAD_IN = 3.0
"""How far before the first station the parent starts, m (away from the second)."""


def _lead_in(
    first: NDArray[np.float64], second: NDArray[np.float64] | None, reachable: BaseGeometry
) -> tuple[float, float]:
    """The start: :data:`LEAD_IN` before ``first``, on the side away from ``second``, where
    the floor allows (else nearer, else at ``first``)."""
    if second is None or np.linalg.norm(second - first) < 1e-9:
        away = np.array([-1.0, 0.0])
    else:
        away = (first - second) / np.linalg.norm(first - second)
    for back in (LEAD_IN, 0.75 * LEAD_IN, 0.5 * LEAD_IN):
        for turn in (0.0, 0.4, -0.4, 0.8, -0.8):
            c, s = math.cos(turn), math.sin(turn)
            d = np.array([c * away[0] - s * away[1], s * away[0] + c * away[1]])
            xy = first + back * d
            if reachable.covers(LineString([first, xy])):
                return float(xy[0]), float(xy[1])
    return float(first[0]), float(first[1])


def _camera_in_world(cam: Mapping[str, Any], pose: MapPose, floor_z: float) -> dict[str, Any]:
    out = dict(cam)
    p = np.asarray(cam["position"], dtype=float)
    d = np.asarray(cam["view_direction"], dtype=float)
    xy = pose.map2world(p[:2])
    dxy = pose.direction2world(d[:2])
    out["position"] = [float(xy[0]), float(xy[1]), float(floor_z + p[2])]
    out["view_direction"] = [float(dxy[0]), float(dxy[1]), float(d[2])]
    return out


def _space_dict(space: BoxedSpace, floor_z: float, map_ref: dict[str, Any]) -> dict[str, Any]:
    """The scenario's space: the room, and the map its boxes are rebuilt from
    (``[space.map]``, :class:`twin.scenario.schema.SpaceMap`)."""
    return {
        "size": list(space.size),
        "origin": list(space.origin),
        "floor_z": floor_z,
        "map": map_ref,
    }


def _space(space: BoxedSpace, floor_z: float) -> Space:
    """The scenario's space with the map's boxes, for the planner's own checks."""
    room = validate_model(
        Space, {"size": list(space.size), "origin": list(space.origin), "floor_z": floor_z}
    )
    return room.with_map_boxes(tuple(map_obstacle(k, b) for k, b in enumerate(space.boxes)))


def _map_ref(floor: FloorMap, map_file: str, pose: MapPose, resolution: float) -> dict[str, Any]:
    """``[space.map]``: the map as the scenario names it, its content's hash, W's pose in it,
    the grid and the reader's options."""
    options = {
        k: list(v) if isinstance(v, (list, tuple, set)) else v for k, v in floor.options.items()
    }
    return {
        "file": map_file,
        "sha256": map_sha256(floor.source),
        "pose": [pose.x, pose.y, math.degrees(pose.yaw)],
        "resolution": resolution,
        "options": options,
    }


def _route(
    graph: RouteGraph, stations: Sequence[NDArray], return_to_start: bool
) -> tuple[NDArray[np.float64], list[float]]:
    """The route from W's origin through ``stations`` (and back), and the heading at each
    station's arrival, deg: the shortest paths on ``graph``, their arcs straightened
    (:func:`_straighten`)."""
    floor = shapely.buffer(graph.reachable, TOLERANCE)
    shapely.prepare(floor)
    targets = [*stations, np.zeros(2)] if return_to_start else list(stations)
    here = np.zeros(2)
    points = [here]
    arrivals: list[float] = []
    for k, goal in enumerate(targets):
        path = _straighten(graph.path(here, goal), floor)
        for p in path[1:]:
            if np.linalg.norm(p - points[-1]) > 1e-6:
                points.append(np.asarray(p, dtype=float))
        if k < len(stations):
            arrivals.append(_heading(points))
        here = np.asarray(goal, dtype=float)
    if len(points) == 1:  # every station at the start: a route needs two points
        points.append(points[0] + (0.5, 0.0))
    return np.array(points), arrivals


def _straighten(path: NDArray[np.float64], floor: BaseGeometry) -> NDArray[np.float64]:
    """``path`` ((K, 2), m: a shortest path, taut round the corners it turns) with the arcs
    it wraps replaced by the fewest straight pieces that stay on ``floor``.

    The floor shrunk by a clearance rounds every corner into an arc of 5 cm pieces, and
    each would be a drive. A piece's line, continued past its end, runs on the free side
    of the corner it wraps (the corner's arc is convex); so two pieces' lines continued
    until they meet replace the pieces between them with one bend. Greedily from the start,
    each bend replaces as many pieces as keep the two lines on ``floor`` and turn by at
    most 90 degrees (a sharper turn in one bend would run far past the corner); the path's
    ends stay where they are.

    Args:
        path: (K, 2), K >= 2. floor: where the path may run (prepared, grown by a tolerance).
    """
    if len(path) < 4:
        return path
    out = [path[0]]
    a = 0  # the piece path[a] -> path[a + 1] the path runs along now, from out[-1]
    last = len(path) - 2  # the last piece
    while a < last:
        here, d_a = out[-1], path[a + 1] - path[a]
        bend = None
        for b in range(a + 2, last + 1):
            d_b = path[b + 1] - path[b]
            cross = float(d_a[0] * d_b[1] - d_a[1] * d_b[0])
            if float(d_a @ d_b) < 0.0:  # a bend of more than 90 degrees
                break
            if abs(cross) < 1e-12:
                continue
            w = path[b] - path[a]
            t = float(w[0] * d_b[1] - w[1] * d_b[0]) / cross  # along d_a from path[a]
            u = float(w[0] * d_a[1] - w[1] * d_a[0]) / cross  # along d_b from path[b]
            if t < 1.0 - 1e-9 or u > 1e-9:  # the lines meet behind the pieces' ends
                break
            q = path[a] + t * d_a
            if not floor.covers(LineString([here, q, path[b + 1]])):
                break
            bend = (b, q)
        if bend is None:
            out.append(path[a + 1])
            a += 1
        else:
            a = bend[0]
            out.append(bend[1])
    out.append(path[-1])
    return np.array(out)


RUN_OUT = 6.0
"""Length of straight route past the last station, m: the children stand up to about 5 m
ahead of the parent's station along the route (:mod:`twin.campaign.plan.formation`), also
at the last one."""


def _run_out(route: NDArray[np.float64], reachable: BaseGeometry) -> NDArray[np.float64]:
    """``route`` with a straight stretch past its end: on in the direction of arrival if
    there is room, else the free direction nearest it (the longest free one if none is
    free for :data:`RUN_OUT`)."""
    end = route[-1]
    arrival = math.atan2(*(route[-1] - route[-2])[::-1]) if len(route) > 1 else 0.0
    turns = [0.0]
    for k in range(1, 9):
        turns += [k * math.pi / 8, -k * math.pi / 8]
    best, best_len = None, 0.0
    for turn in turns:
        heading = arrival + turn
        step = np.array([math.cos(heading), math.sin(heading)])
        free = _free_length(reachable, end, step, RUN_OUT)
        if free >= RUN_OUT:
            return np.vstack([route, end + RUN_OUT * step])
        if free > best_len:
            best, best_len = step, free
    if best is None or best_len < 0.5:
        return route
    return np.vstack([route, end + best_len * best])


def _free_length(reachable: BaseGeometry, start: NDArray, step: NDArray, most: float) -> float:
    """How far from ``start`` along ``step`` (a unit vector) stays in ``reachable``, up to
    ``most``, m (in 0.25 m steps)."""
    length = 0.0
    while length < most:
        nxt = min(length + 0.25, most)
        if not reachable.covers(LineString([start, start + nxt * step])):
            break
        length = nxt
    return length


def _heading(points: Sequence[NDArray]) -> float:
    if len(points) < 2:
        return 0.0
    d = points[-1] - points[-2]
    return float(np.degrees(np.arctan2(d[1], d[0])))


def _start_prism(
    floor: FloorMap, pose: MapPose, route: NDArray, children: Sequence[NDArray]
) -> NDArray[np.float64] | None:
    """Where to leave a prism near the start to close the loop (W, m): the first place,
    trying behind the start first, that is on the floor clear of walls, in plain sight of
    the start, off the route and away from the children's starts; None if none is."""
    free = pose.geometry2world(floor.reachable(START_PRISM_CLEARANCE))
    path = LineString(route) if len(route) > 1 else Point(0.0, 0.0)
    ahead = (
        math.atan2(route[1][1] - route[0][1], route[1][0] - route[0][0]) if len(route) > 1 else 0.0
    )
    for r in START_PRISM_DISTANCES:
        for turn in START_PRISM_TURNS_DEG:
            a = ahead + math.pi + math.radians(turn)
            xy = np.array([r * math.cos(a), r * math.sin(a)])
            if (
                free.contains(LineString([(0.0, 0.0), tuple(xy)]))
                and path.distance(Point(*xy)) >= START_PRISM_OFF_ROUTE
                and all(np.linalg.norm(xy - c) >= START_PRISM_OFF_ROUTE for c in children)
            ):
                return xy
    return None


def _children(floor: FloorMap, pose: MapPose) -> list[NDArray[np.float64]]:
    """The children's starts in W (:func:`twin.planning.regions.children_at`)."""
    out = children_at(floor.reachable(CHILD_CLEARANCE), (pose.x, pose.y), pose.yaw)
    if out is None:  # the start was checked for room: not reached
        raise MapError(floor.source, _no_room(pose.x, pose.y))
    return out


def _no_room(x: float, y: float) -> str:
    return (
        f"no room beside the start ({x:.2f}, {y:.2f}) in the map's frame for the two "
        f"children: each stands {CHILD_CLEARANCE:.2f} m clear of walls, 1.2 to 2.7 m from "
        "the parent in plain sight of it"
    )


def _region(
    floor: FloorMap,
    cameras: Sequence[Mapping[str, Any]],
    passable: BaseGeometry,
    parent_free: BaseGeometry,
    start: tuple[float, float, float] | None,
    floor_z: float,
) -> tuple[Polygon, dict[str, str]]:
    """The piece of ``passable`` (the floor the parent's centre may pass, doorways
    included) the plan keeps to (the given start's, else the one most cameras' floor views
    lie on) and the cameras whose view lies elsewhere, each with where it is and why
    (:mod:`twin.planning.regions`). A given start must be on ``parent_free`` (the floor
    with the formation's clearance).

    Raises:
        MapError: a given start off the floor, on a piece no camera's view lies on, or
            without room for the children; no camera reachable. The message gives the
            place in the map's frame and a ``--start`` that works where one is found.
    """
    pieces = floor_pieces(passable)
    views = {str(c["name"]): _floor_view(floor, c, floor_z) for c in cameras}
    counts = view_counts(pieces, views, PASSAGE_CLEARANCE)
    main = main_piece(pieces, counts)
    region = main
    if start is not None:
        x, y, yaw = (float(v) for v in start)
        child_free = floor.reachable(CHILD_CLEARANCE)
        at = piece_at(pieces, (x, y))
        if at is None or not parent_free.contains(Point(x, y)):
            why = (
                f"the start ({x:.2f}, {y:.2f}) in the map's frame is not on the floor with the "
                f"robots' clearance ({FORMATION_CLEARANCE:.2f} m from every wall and obstacle)"
            )
        elif not any(c.sum() > 0 and c[at] >= c.max() for c in counts.values()):
            area = pieces[at].area
            cut_off = [
                f"{name} {why}"
                for name in views
                if (
                    why := unreachable_why(
                        floor, pieces, at, counts[name], views[name], PASSAGE_CLEARANCE
                    )
                )
            ]
            why = (
                f"the start ({x:.2f}, {y:.2f}) in the map's frame is on a piece of floor "
                f"({area:.1f} m^2) that no camera's floor view lies on ({'; '.join(cut_off)})"
            )
        elif children_at(child_free, (x, y), yaw) is None:
            why = _no_room(x, y)
        else:
            why = ""
            region = at
        if why:
            place = group_start(pieces[main].intersection(parent_free), child_free, (x, y), yaw)
            hint = (
                f"; try --start {place[0]:.2f} {place[1]:.2f} {math.degrees(yaw):g}"
                if place is not None
                else "; no place on the floor the cameras look at has room for the group"
            )
            raise MapError(floor.source, why + hint)
    unreachable: dict[str, str] = {}
    for cam in cameras:
        cam_name = str(cam["name"])
        why = unreachable_why(
            floor, pieces, region, counts[cam_name], views[cam_name], PASSAGE_CLEARANCE
        )
        if why is not None:
            x, y = np.asarray(cam["position"], dtype=float)[:2]
            unreachable[cam_name] = f"at ({x:.2f}, {y:.2f}): {why}"
    if len(unreachable) == len(cameras):
        listing = "; ".join(f"{k} {v}" for k, v in unreachable.items())
        raise MapError(floor.source, f"the robots can reach no camera's floor view: {listing}")
    return pieces[region], unreachable


def _floor_view(floor: FloorMap, cam: Mapping[str, Any], floor_z: float) -> NDArray[np.float64]:
    """(N, 2) the camera's floor-view points on the map's free floor, map frame, m."""
    camera = validate_model(CameraConfig, _camera_in_world(cam, MapPose(), floor_z)).tsai()
    view = floor_view(camera, floor_z, max_range=60.0)[:, :2]
    if len(view) == 0:
        return view
    return view[shapely.contains_xy(floor.free, view[:, 0], view[:, 1])]


def _group_start(
    floor: FloorMap, region: BaseGeometry, near: tuple[float, float]
) -> tuple[float, float]:
    """The automatic start: the place of ``region`` nearest ``near`` where the group fits
    (:func:`twin.planning.regions.group_start`), else anywhere on ``region`` (on a 1 m
    grid).

    Raises:
        MapError: none, naming ``near`` in the map's frame and ``--start``.
    """
    child_free = floor.reachable(CHILD_CLEARANCE)
    place = group_start(region, child_free, near)
    if place is None:
        place = group_start(region, child_free, near, spacing=1.0, tries=2000)
    if place is None:
        raise MapError(
            floor.source,
            f"no place on the floor the cameras look at, around ({near[0]:.2f}, "
            f"{near[1]:.2f}) in the map's frame before the first station, has room for the "
            "parent and both children: give --start X Y YAW_DEG at a place with room",
        )
    return place


def _scenario(
    *,
    name: str,
    seed: int,
    space: BoxedSpace,
    map_ref: dict[str, Any],
    floor_z: float,
    cameras: list[dict[str, Any]],
    children: list[NDArray],
    route: NDArray,
    return_to_start: bool,
    start_prism: NDArray | None,
    visits: list[tuple[str, NDArray, float]],
    site: dict[str, Any],
    min_visible: float = STATION_NEED,
) -> dict[str, Any]:
    controls = (
        []
        if start_prism is None
        else [
            {
                "name": "start_prism",
                "position": [float(start_prism[0]), float(start_prism[1]), 0.0],
                "sight_radius_m": START_PRISM_SIGHT,
            }
        ]
    )
    return {
        "name": name,
        "description": f"Planned from the map {site['map']}: {len(cameras)} cameras.",
        "seed": seed,
        "space": _space_dict(space, floor_z, map_ref),
        "cameras": cameras,
        "robots": {
            "parent": {"name": "parent", "model": "pioneer3at", "start_xy": [0.0, 0.0]},
            "children": [
                {"name": f"child{k + 1}", "model": "pioneer3dx", "start_xy": c.tolist()}
                for k, c in enumerate(children)
            ],
        },
        "route": {"waypoints": route.tolist(), "return_to_start": return_to_start},
        "control_points": controls,
        "calibration": {
            "visits": [
                {"camera": cam, "station": xy.tolist(), "yaw_deg": heading}
                for cam, xy, heading in visits
            ],
            **({} if min_visible == STATION_NEED else {"min_visible_fraction": min_visible}),
        },
        "site": site,
    }
