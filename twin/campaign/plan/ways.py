"""A child's way to a stop past the robots that stand: straight where that is clear, else
through one corner beside the straight line, else the shortest way on the floor round the
robots (:class:`twin.planning.route.RouteGraph`).

A child driving to a data stop in a camera's view crosses ground the campaign's route never
planned, where the parent and the other child stand. A straight drive through one of them
pushes it: a pushed child is measured again, but a pushed parent has moved its station and
every point measured after it is in another frame. So a way keeps each standing robot at
its radius, the driving child's and a margin; and the map's walls and obstacles at a
clearance.

A child stands where its last drive left it, which may be nearer a wall or a robot than a
way keeps (a drive that ended against the wall): it may leave on a way that takes it no
nearer than it stands, as it leaves a robot it stopped beside.

Planned on the map and the campaign's estimates of where the robots stand.
"""

from __future__ import annotations

import itertools

import numpy as np
import shapely
from numpy.typing import ArrayLike, NDArray
from shapely.ops import nearest_points

from twin.campaign.plan.clearance import path_clear
from twin.planning.route import NoPathError, RouteGraph
from twin.scenario.geometry import obstacles_near, rectangle
from twin.scenario.schema import Space

WAY_CLEARANCE = 0.3
"""Distance a way keeps between the driving child's centre and walls or obstacles, m (its
radius, 0.29 m: a data stop may stand close to a wall, and the way must reach it)."""

ROBOT_MARGIN = 0.15
"""Room a way keeps beyond the two robots' radii, m: the driving child's heading and
stopping errors over a few metres."""

CORNER_FRACTIONS = (0.5, 0.25, 0.75)
"""Where along the straight line a corner is tried (fraction of the way)."""

CORNER_OFFSETS = (0.75, 1.5, 2.25, 3.0)
"""How far to either side of the straight line a corner is tried, m."""

WAY_REACH = 6.0
"""How far beyond the box round a way's two ends the floor is searched for a way round
the robots, m."""

WAY_MARGIN = 0.01
"""How much wider than the distance kept the map's obstacles and the standing robots are
drawn on the floor a way round them is searched on, m: a way bends at their corners, and
a point at exactly a clearance does not keep it (:func:`leg_clear`); a robot's disc is a
polygon inside its circle (by less than this)."""


def _passes(
    a: NDArray[np.float64], b: NDArray[np.float64], centres: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(K,) least distance of each (K, 2) centre from the segment a-b, m."""
    d = b - a
    n2 = max(float(d @ d), 1e-12)
    t = np.clip((centres - a) @ d / n2, 0.0, 1.0)
    return np.linalg.norm(a + t[:, None] * d - centres, axis=1)


def map_clearance(space: Space, xy: ArrayLike) -> float:
    """How far a robot centred at (2,) ``xy`` stands from the map, m, as
    :func:`twin.campaign.plan.clearance.robot_fits` measures it: from the walls, and from
    each obstacle's footprint grown on every side (a rectangle, not rounded at its corners);
    0 or less inside a wall or an obstacle."""
    p = np.asarray(xy, dtype=float).reshape(2)
    (x0, x1), (y0, y1) = space.x_range, space.y_range
    room = min(p[0] - x0, x1 - p[0], p[1] - y0, y1 - p[1])
    for ob in space.obstacles:
        d = p - np.asarray(ob.center, dtype=float)
        c, s = np.cos(ob.yaw), np.sin(ob.yaw)
        along, across = abs(c * d[0] + s * d[1]), abs(-s * d[0] + c * d[1])
        room = min(room, max(along - 0.5 * ob.size[0], across - 0.5 * ob.size[1]))
    return float(room)


def leg_clear(
    space: Space,
    start: ArrayLike,
    end: ArrayLike,
    robots: ArrayLike,
    keep: ArrayLike,
    clearance: float = WAY_CLEARANCE,
) -> bool:
    """Whether a child can drive straight from ``start`` to ``end`` ((2,) m) keeping
    ``clearance`` from the map and ``keep[k]`` from each robot ((K, 2) centres, m).

    A robot the child already stands nearer than ``keep`` does not block a drive that
    takes it no nearer (a child leaves the side of a robot it stopped beside).
    """
    return robots_clear(start, end, robots, keep) and path_clear(space, start, end, clearance)


def robots_clear(start: ArrayLike, end: ArrayLike, robots: ArrayLike, keep: ArrayLike) -> bool:
    """Whether a child can drive straight from ``start`` to ``end`` ((2,) m) keeping
    ``keep[k]`` from each robot ((K, 2) centres, m); the map is not looked at.

    A robot the child already stands nearer than ``keep`` does not block a drive that
    takes it no nearer (a child leaves the side of a robot it stopped beside).
    """
    a = np.asarray(start, dtype=float).reshape(2)
    b = np.asarray(end, dtype=float).reshape(2)
    centres = np.asarray(robots, dtype=float).reshape(-1, 2)
    if not len(centres):
        return True
    room = np.minimum(np.asarray(keep, dtype=float), np.linalg.norm(centres - a, axis=1))
    return not (_passes(a, b, centres) < room - 1e-9).any()


def way_to(
    space: Space,
    start: ArrayLike,
    goal: ArrayLike,
    robots: ArrayLike,
    keep: ArrayLike,
    clearance: float = WAY_CLEARANCE,
) -> list[NDArray[np.float64]] | None:
    """The corners of a way from ``start`` to ``goal`` ((2,) m) that keeps clear of the map
    and of the robots (:func:`leg_clear`): none where the straight drive is clear, else
    the one corner (beside the straight line: :data:`CORNER_FRACTIONS`,
    :data:`CORNER_OFFSETS`) of the shortest such way; None where none is clear.

    A start nearer the map than ``clearance`` (:func:`map_clearance`) is left by a first
    leg that keeps as far as the start stands; the corner and the last leg keep
    ``clearance``. A start inside a wall or an obstacle has no way.

    Args:
        space: the map. start, goal: (2,) m.
        robots: (K, 2) the standing robots' centres, m. keep: (K,) the distance to keep
            from each, m.
        clearance: from walls and obstacles, m.
    """
    a = np.asarray(start, dtype=float).reshape(2)
    b = np.asarray(goal, dtype=float).reshape(2)
    # A point at exactly a clearance does not fit it (robot_fits): leave just inside.
    leave = min(clearance, map_clearance(space, a) - 1e-9)
    if leave <= 0.0:
        return None
    if leg_clear(space, a, b, robots, keep, leave):
        return []
    d = b - a
    length = float(np.linalg.norm(d))
    if length < 1e-9:
        return None
    side = np.array([-d[1], d[0]]) / length
    corners = [
        a + f * d + sign * offset * side
        for f in CORNER_FRACTIONS
        for offset in CORNER_OFFSETS
        for sign in (1.0, -1.0)
    ]
    corners.sort(key=lambda c: float(np.linalg.norm(c - a) + np.linalg.norm(b - c)))
    for corner in corners:
        if leg_clear(space, a, corner, robots, keep, leave) and leg_clear(
            space, corner, b, robots, keep, clearance
        ):
            return [corner]
    return _way_round(space, a, b, robots, keep, leave, clearance)


def _way_round(
    space: Space,
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    robots: ArrayLike,
    keep: ArrayLike,
    leave: float,
    clearance: float,
) -> list[NDArray[np.float64]] | None:
    """The corners of the shortest way from ``a`` to ``b`` ((2,) m) on the floor near them
    (:data:`WAY_REACH`) kept ``clearance`` from the walls and obstacles (their footprints
    grown, rectangles as :func:`map_clearance` measures) and ``keep[k]`` from each robot
    (no more than ``a`` stands from it), each leg checked with :func:`leg_clear`; None
    where there is none (a robot or the map closes the way).

    A start nearer the map than ``clearance`` (``leave`` < ``clearance``) first steps
    straight off to the nearest point of that floor, keeping ``leave``: the rest of the way
    keeps ``clearance``, as a way that leaves a wall it stopped beside does.
    """
    centres = np.asarray(robots, dtype=float).reshape(-1, 2)
    away = np.linalg.norm(centres - a, axis=1)
    room = np.minimum(np.asarray(keep, dtype=float), away)
    lo = np.minimum(a, b) - WAY_REACH
    hi = np.maximum(a, b) + WAY_REACH
    (x0, x1), (y0, y1) = space.x_range, space.y_range
    grow = clearance + WAY_MARGIN
    window = shapely.box(
        max(lo[0], x0 + grow), max(lo[1], y0 + grow), min(hi[0], x1 - grow), min(hi[1], y1 - grow)
    )
    near = obstacles_near(space.obstacles, np.array([lo, hi]), grow)
    blocked = [rectangle(ob.center, np.add(ob.size[:2], 2 * grow), ob.yaw) for ob in near]
    blocked += [
        shapely.Point(c).buffer(min(r + WAY_MARGIN, d))
        for c, r, d in zip(centres, room, away, strict=True)
        if d > 0.0
    ]
    floor = window.difference(shapely.union_all(blocked)) if blocked else window
    legs = [a]
    if leave < clearance and not floor.covers(shapely.Point(a)):
        if floor.is_empty:
            return None
        _, nearest = nearest_points(shapely.Point(a), floor)
        legs.append(np.array([nearest.x, nearest.y]))
        if not leg_clear(space, a, legs[-1], centres, room, leave):
            return None
    try:
        path = RouteGraph(floor).path(legs[-1], b)
    except NoPathError:
        return None
    legs += [np.asarray(c, dtype=float) for c in path[1:-1]] + [b]
    for i, (start, end) in enumerate(itertools.pairwise(legs)):
        if not leg_clear(space, start, end, centres, room, leave if i == 0 else clearance):
            return None
    return legs[1:-1]
