"""Where a site plan starts: the piece of floor the parent keeps to from its start (the
cameras whose floor view lies elsewhere named with why), the automatic start where the
whole group fits before the first station, the children's places beside it, and the prism
left near it to close the loop.

Everything is in the map's frame unless said otherwise (W is the parent's instrument frame
at the start; :class:`twin.planning.frames.MapPose` maps between them).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry import LineString, Point, Polygon
from shapely.geometry.base import BaseGeometry

from twin.planning.floor_map import FloorMap, MapError
from twin.planning.frames import MapPose
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
from twin.planning.route import NoPathError, RouteGraph
from twin.planning.site_route import FORMATION_CLEARANCE, PASSAGE_CLEARANCE
from twin.planning.stations import Station
from twin.planning.tour import order_visits
from twin.scenario.geometry import floor_view
from twin.scenario.loader import validate_model
from twin.scenario.schema import CameraConfig

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


def first_two(
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


def lead_in(
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


def camera_in_world(cam: Mapping[str, Any], pose: MapPose, floor_z: float) -> dict[str, Any]:
    out = dict(cam)
    p = np.asarray(cam["position"], dtype=float)
    d = np.asarray(cam["view_direction"], dtype=float)
    xy = pose.map2world(p[:2])
    dxy = pose.direction2world(d[:2])
    out["position"] = [float(xy[0]), float(xy[1]), float(floor_z + p[2])]
    out["view_direction"] = [float(dxy[0]), float(dxy[1]), float(d[2])]
    return out


def loop_prism(
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


def children_of(floor: FloorMap, pose: MapPose) -> list[NDArray[np.float64]]:
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


def start_region(
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
    camera = validate_model(CameraConfig, camera_in_world(cam, MapPose(), floor_z)).tsai()
    view = floor_view(camera, floor_z, max_range=60.0)[:, :2]
    if len(view) == 0:
        return view
    return view[shapely.contains_xy(floor.free, view[:, 0], view[:, 1])]


def automatic_start(
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
