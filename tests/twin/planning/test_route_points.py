"""The site's route turns a corner in a few straight pieces, not in the 5 cm pieces of the
arc that shrinking the floor by a clearance rounds it into, and stays on that floor."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from twin.planning import floor_shapes as fs
from twin.planning.route import TOLERANCE, RouteGraph
from twin.planning.site_route import straighten


def _floor(width: float, turn_deg: float, clearance: float):
    free = fs.corridor_turn(width, turn_deg, 12.0)
    reachable = free.buffer(-clearance)
    grown = shapely.buffer(reachable, TOLERANCE)
    shapely.prepare(grown)
    return reachable, grown


def _length(path) -> float:
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())


def _ends(width: float, turn_deg: float):
    """A start 1 m into the first leg and a goal 2 m before the far leg's end, mid-corridor."""
    if turn_deg > 135.0:
        return np.array([1.0, 0.0]), np.array([2.0, width + fs.WALL])
    a = np.radians(turn_deg)
    return np.array([1.0, 0.0]), np.array([12.0, 0.0]) + 10.0 * np.array([np.cos(a), np.sin(a)])


@pytest.mark.parametrize(("width", "turn_deg"), [(2.4, 90.0), (3.0, 135.0), (2.4, 180.0)])
def test_a_corner_is_turned_in_few_pieces_on_the_floor(width, turn_deg):
    clearance = 0.95
    reachable, grown = _floor(width, turn_deg, clearance)
    exact = RouteGraph(reachable).path(*_ends(width, turn_deg))
    assert len(exact) > 10  # the arcs' pieces
    route = straighten(exact, grown)
    assert len(route) <= 6
    np.testing.assert_array_equal(route[0], exact[0])
    np.testing.assert_array_equal(route[-1], exact[-1])
    assert grown.covers(shapely.LineString(route))
    # Outside the arc, by bends of at most 90 degrees: longer than the taut path by at
    # most a square's perimeter round the arc's circle less the circle's, (4 - pi) r.
    assert _length(exact) <= _length(route) <= _length(exact) + (4 - np.pi) * clearance


def test_a_short_path_is_kept():
    _, grown = _floor(2.4, 90.0, 0.95)
    path = np.array([[1.0, 0.0], [11.0, 0.0], [12.0, 9.0]])
    np.testing.assert_array_equal(straighten(path, grown), path)


def test_a_bend_through_a_doorway_stays_in_the_door():
    # A door 1.2 m wide and a clearance that just passes it: the route turns into the door
    # and out of it round the far jamb; one bend for both turns would be in the wall.
    free = fs.dead_end(2.4, 16.0, (5.0, 4.0), 1.2)
    reachable = free.buffer(-0.55)
    grown = shapely.buffer(reachable, TOLERANCE)
    shapely.prepare(grown)
    exact = RouteGraph(reachable).path((1.0, 0.0), (9.8, 2.2))
    route = straighten(exact, grown)
    assert len(route) <= 4 < len(exact)
    assert grown.covers(shapely.LineString(route))
