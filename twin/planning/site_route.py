"""The parent's route of a site plan, in W: the graph it is planned on (the widest
clearance that joins the start and every station, down to a doorway's), kept off the boxes
as the scenario's loader checks them, through the stations in order with straight pieces
at its corners, and run out past the last station.

The clearances here are the plan's: the formation's (where the group drives and stands),
the stations' and the passage's (a doorway the parent passes alone).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry import LineString, Point
from shapely.geometry.base import BaseGeometry
from shapely.ops import nearest_points

from twin.planning.boxes import BoxedSpace
from twin.planning.floor_map import FloorMap, MapError
from twin.planning.frames import MapPose
from twin.planning.route import TOLERANCE, RouteGraph
from twin.planning.stations import Station
from twin.scenario.cross_checks import PARENT_CLEARANCE
from twin.scenario.robots import PIONEER3AT

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


def route_graph(
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


def clear_of_boxes(graph: RouteGraph, boxed: BoxedSpace) -> RouteGraph:
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


def route_through(
    graph: RouteGraph, stations: Sequence[NDArray], return_to_start: bool
) -> tuple[NDArray[np.float64], list[float]]:
    """The route from W's origin through ``stations`` (and back), and the heading at each
    station's arrival, deg: the shortest paths on ``graph``, their arcs straightened
    (:func:`straighten`)."""
    floor = shapely.buffer(graph.reachable, TOLERANCE)
    shapely.prepare(floor)
    targets = [*stations, np.zeros(2)] if return_to_start else list(stations)
    here = np.zeros(2)
    points = [here]
    arrivals: list[float] = []
    for k, goal in enumerate(targets):
        path = straighten(graph.path(here, goal), floor)
        for p in path[1:]:
            if np.linalg.norm(p - points[-1]) > 1e-6:
                points.append(np.asarray(p, dtype=float))
        if k < len(stations):
            arrivals.append(_heading(points))
        here = np.asarray(goal, dtype=float)
    if len(points) == 1:  # every station at the start: a route needs two points
        points.append(points[0] + (0.5, 0.0))
    return np.array(points), arrivals


def straighten(path: NDArray[np.float64], floor: BaseGeometry) -> NDArray[np.float64]:
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


def run_out(route: NDArray[np.float64], reachable: BaseGeometry) -> NDArray[np.float64]:
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
