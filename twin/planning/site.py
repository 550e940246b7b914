"""A campaign planned on a map: the scenario ``twin site`` writes.

From a floor map (:mod:`twin.planning.maps`) and the cameras as installed (their
approximate poses and nominal intrinsics, in the map's frame), the planner:

1. keeps to the floor the parent reaches from its start (:mod:`twin.planning.regions`:
   the cameras whose floor view lies elsewhere are left out, named with why) and takes
   the start (given, or before the first station where the group fits, heading along the
   map's x-axis) as the world frame W;
2. lays the map's blocked floor as boxes in W (:mod:`twin.planning.boxes`), which the
   scenario does not write out: it references the map (``[space.map]``) and its hash;
   a camera on a wall's face is moved off the wall's box
   (:mod:`twin.planning.site_cameras`, which also reads the cameras file);
3. chooses each camera's station (:mod:`twin.planning.stations`), one from which the
   children reach the data stops past the standing parent where one is;
4. orders the visits by the shortest tour over the stations (:mod:`twin.planning.tour`)
   unless the user gives the order, with a return to the start if asked;
5. routes the parent between them by shortest paths with the CPS formation's clearance
   (:mod:`twin.planning.route`);
6. places the children beside the start.

The result is an ordinary scenario (a mapping, validated by the scenario loader, written
by :mod:`twin.planning.site_scenario`) with a ``[site]`` section that keeps the map and
the map-to-W transform.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.campaign.plan.ways import WAY_CLEARANCE
from twin.planning.boxes import DEFAULT_RESOLUTION, BoxedSpace, boxed_space
from twin.planning.ceiling import check_ceiling, site_ceiling
from twin.planning.floor_map import FloorMap, MapError
from twin.planning.frames import MapPose
from twin.planning.route import NoPathError, RouteGraph
from twin.planning.site_cameras import CAMERA_KEYS, clear_cameras, read_cameras
from twin.planning.site_route import (
    FORMATION_CLEARANCE,
    PASSAGE_CLEARANCE,
    STATION_CLEARANCE,
    clear_of_boxes,
    route_graph,
    route_through,
    run_out,
)
from twin.planning.site_scenario import map_reference, scenario_dict
from twin.planning.site_start import (
    automatic_start,
    camera_in_world,
    children_of,
    first_two,
    lead_in,
    loop_prism,
    start_region,
)
from twin.planning.site_stations import (
    STATION_FLOOR,
    STATION_NEED,
    StopsSeen,
    gives_data_from,
    site_stations,
    visible_from,
)
from twin.planning.stations import (
    Station,
)
from twin.planning.tour import order_visits
from twin.scenario.robots import INSTRUMENT_HEIGHT

__all__ = [
    "CAMERA_KEYS",
    "FORMATION_CLEARANCE",
    "PASSAGE_CLEARANCE",
    "STATION_FLOOR",
    "STATION_NEED",
    "SitePlan",
    "plan_site",
    "read_cameras",
]


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
        moved: the cameras that stood just inside a box of the blocked floor (on a wall's
            face), moved off it, each with from where, to where and how far (map frame:
            :func:`twin.planning.site_cameras.clear_cameras`).
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
    moved: dict[str, str] = dataclasses.field(default_factory=dict)


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
    passable, unreachable = start_region(
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
    child_free = floor.reachable(WAY_CLEARANCE)
    chosen = list(dict.fromkeys(wanted if wanted is not None else names))
    # The stations are chosen in the map's frame when the start is to be chosen after them.
    pose = MapPose() if start is None else MapPose(*(float(v) for v in start))
    boxed = boxed_space(floor, pose, resolution)
    cameras, moved = clear_cameras(floor, cameras, pose, boxed, floor_z)
    if start is None:
        # Stations first, in the map's frame; then the start just before the first of the
        # best open tour over them, so that the route runs on rather than back and forth.
        seen: StopsSeen = {}
        in_map, hidden = site_stations(
            cameras, chosen, pose, boxed, station_free, child_free, floor_z, avoid, seen=seen
        )
        cameras, names, wanted = _without(floor, hidden, cameras, wanted, unreachable)
        graph = RouteGraph(passable)
        first, second = first_two(graph, in_map, wanted, floor.source)
        pose = MapPose(
            *automatic_start(floor, parent_free, lead_in(first, second, parent_free)), 0.0
        )
        # The start known: a station whose data stops lie on its side of a passage the
        # standing parent closes leaves the children, ahead of it, cut off: chosen again.
        home = np.array([pose.x, pose.y])
        cut = [
            c
            for c in in_map
            if not gives_data_from(cameras, c, in_map[c].xy, boxed, child_free, floor_z, home, seen)
        ]
        if cut:
            again, _ = site_stations(
                cameras, cut, MapPose(), boxed, station_free, child_free, floor_z, avoid, home, seen
            )
            in_map = {**in_map, **again}
        stations = {
            k: dataclasses.replace(
                st, xy=pose.map2world(st.xy), view_centre=pose.map2world(st.view_centre)
            )
            for k, st in in_map.items()
        }
        boxed = boxed_space(floor, pose, resolution)
        # The boxes laid in the chosen W: the cameras checked again.
        cameras, again = clear_cameras(floor, cameras, pose, boxed, floor_z)
        moved = {**again, **moved}
    else:
        stations, hidden = site_stations(
            cameras, chosen, pose, boxed, station_free, child_free, floor_z, avoid, np.zeros(2)
        )
        cameras, names, wanted = _without(floor, hidden, cameras, wanted, unreachable)
    cams_w = {c["name"]: camera_in_world(c, pose, floor_z) for c in cameras}
    # What each station sees in the boxes laid in W, as the scenario's check computes it:
    # a few per cent off what the search found in the map's frame.
    seen_w = {c: visible_from(boxed, cams_w[c], st.xy, floor_z) for c, st in stations.items()}
    partial = {c: v for c, v in seen_w.items() if v < STATION_NEED}
    reach_w = pose.geometry2world(parent_free)
    graph = clear_of_boxes(route_graph(floor, pose, reach_w, stations), boxed)
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
    route, arrivals = route_through(graph, [stations[c].xy for c in sequence], return_to_start)
    if not return_to_start:
        route = run_out(route, reach_w)
    children = children_of(floor, pose)
    prism = loop_prism(floor, pose, route, children) if return_to_start else None
    scenario = scenario_dict(
        name=name,
        seed=seed,
        space=boxed,
        map_ref=map_reference(floor, map_file or floor.source, pose, resolution),
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
        min_visible=_min_visible(partial) if partial else None,
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
        moved,
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
