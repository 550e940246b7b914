"""Shortest routes with clearance: known lengths, never leaving the reachable floor, no path
through a door that is too narrow, corridor widths."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
import shapely
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from shapely.geometry import LineString, MultiPolygon, Point, Polygon, box

from twin.planning.route import (
    NoPathError,
    RouteGraph,
    _benchmark_site,
    corridor_width,
    shortest_path,
)

CLEARANCE = 0.3


def _length(path: np.ndarray) -> float:
    return float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))


def _room_with_pillar(radius: float = 1.0) -> Polygon:
    """A 10 x 10 m room with a round pillar in the middle, shrunk by the clearance."""
    free = box(0, 0, 10, 10).difference(Point(5, 5).buffer(radius, quad_segs=64))
    return free.buffer(-CLEARANCE)


def _cluttered_room() -> Polygon:
    """A 10 x 10 m room with pillars, a counter and an L-shaped wall, shrunk."""
    obstacles = [
        Point(3, 3).buffer(0.5),
        Point(7, 6).buffer(0.8, quad_segs=4),
        box(1, 6, 4, 6.5),
        box(5.5, 1, 6, 4.5),
        box(5.5, 4, 9, 4.5),
    ]
    return box(0, 0, 10, 10).difference(shapely.union_all(obstacles)).buffer(-CLEARANCE)


def _two_rooms(door: float) -> Polygon:
    """Two 5 x 5 m rooms on either side of a 0.2 m wall with a door ``door`` m wide."""
    wall = box(5, 0, 5.2, 5).difference(box(5, 2.5 - door / 2, 5.2, 2.5 + door / 2))
    return box(0, 0, 10.2, 5).difference(wall).buffer(-CLEARANCE)


ROOM = _cluttered_room()
EXACT = RouteGraph(ROOM)
SIMPLIFIED = RouteGraph(ROOM, simplify=0.02)


def test_path_around_a_pillar_has_the_analytic_length() -> None:
    reachable = _room_with_pillar(radius=1.0)
    start, goal = (1.0, 5.0), (9.0, 5.0)
    d, r = 4.0, 1.0 + CLEARANCE  # centre to each end; the pillar grown by the clearance
    truth = 2.0 * math.sqrt(d**2 - r**2) + r * (math.pi - 2.0 * math.acos(r / d))

    path = shortest_path(reachable, start, goal)
    assert_allclose(path[0], start)
    assert_allclose(path[-1], goal)
    assert _length(path) == pytest.approx(truth, rel=0.01)
    graph = RouteGraph(reachable, simplify=0.02)  # simplified: a little longer, within 1 %
    assert graph.length(start, goal) == pytest.approx(truth, rel=0.01)
    assert graph.length(start, goal) >= _length(path) - 1e-9
    assert len(graph.points) < len(RouteGraph(reachable, simplify=0.0).points)


def test_a_visible_goal_is_reached_in_a_straight_line() -> None:
    path = EXACT.path((0.5, 0.5), (9.5, 0.5))
    assert_allclose(path, [[0.5, 0.5], [9.5, 0.5]])
    assert EXACT.length((2.0, 8.0), (2.0, 8.0)) == 0.0


_GRID = np.stack(np.meshgrid(np.arange(0.0, 10.0, 0.05), np.arange(0.0, 10.0, 0.05)), -1)
_GRID = _GRID.reshape(-1, 2)
_INSIDE = _GRID[shapely.covers(ROOM, shapely.points(_GRID))]
# a reachable grid point, moved by up to 2 mm (and kept only if still reachable)
point = st.builds(
    lambda k, dx, dy: (float(_INSIDE[k, 0] + dx), float(_INSIDE[k, 1] + dy)),
    st.integers(0, len(_INSIDE) - 1),
    st.floats(-0.002, 0.002),
    st.floats(-0.002, 0.002),
)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(start=point, goal=point, via=point)
def test_a_path_never_leaves_the_reachable_floor_and_is_shortest(start, goal, via) -> None:
    for p in (start, goal, via):
        assume(ROOM.covers(Point(p)))
    path = EXACT.path(start, goal)
    assert path.shape[1] == 2
    assert_allclose(path[0], start)
    assert_allclose(path[-1], goal)
    assert ROOM.buffer(1e-6).covers(LineString(path))
    length = _length(path)
    assert length >= math.dist(start, goal) - 1e-9
    # no detour through a third point is shorter
    assert length <= EXACT.length(start, via) + EXACT.length(via, goal) + 1e-9
    # The simplified graph promises near-shortest paths between points at least twice its
    # tolerance inside the floor (one on the floor's very edge, at the back of a pocket,
    # may not see the shrunk corners that lead to it).
    simplified = SIMPLIFIED.path(start, goal)
    assert ROOM.buffer(1e-6).covers(LineString(simplified))
    inner = ROOM.buffer(-2 * SIMPLIFIED.simplify)
    if inner.covers(Point(start)) and inner.covers(Point(goal)):
        assert length - 1e-9 <= _length(simplified) <= 1.02 * length + 0.05


def test_a_door_narrower_than_twice_the_clearance_has_no_path() -> None:
    start, goal = (2.0, 2.5), (8.0, 2.5)
    with pytest.raises(NoPathError, match=r"separate regions") as caught:
        shortest_path(_two_rooms(door=0.5), start, goal)
    assert "(2.000, 2.500)" in str(caught.value)
    assert "(8.000, 2.500)" in str(caught.value)
    assert isinstance(caught.value, ValueError)

    wide = _two_rooms(door=1.0)
    path = shortest_path(wide, start, goal)
    assert wide.buffer(1e-6).covers(LineString(path))
    crossing = LineString(path).intersection(LineString([(5.1, 0), (5.1, 5)]))
    assert abs(crossing.y - 2.5) <= 0.5 - CLEARANCE + 1e-6


def test_points_outside_the_reachable_floor_have_no_path() -> None:
    with pytest.raises(NoPathError, match=r"the start \(3.000, 3.000\) is outside"):
        EXACT.path((3.0, 3.0), (9.0, 9.0))  # inside a pillar
    with pytest.raises(NoPathError, match=r"the goal \(0.100, 5.000\) is outside"):
        EXACT.path((9.0, 9.0), (0.1, 5.0))  # closer to the wall than the clearance
    with pytest.raises(ValueError, match="start must be a finite point"):
        EXACT.path((math.nan, 1.0), (9.0, 9.0))


def test_separate_pieces_of_a_multipolygon_are_separate_regions() -> None:
    reachable = MultiPolygon([box(0, 0, 4, 4), box(6, 0, 10, 4)])
    graph = RouteGraph(reachable)
    assert graph.region_of((1, 1)) != graph.region_of((8, 1))
    assert graph.region_of((5, 1)) is None
    with pytest.raises(NoPathError, match="separate regions"):
        graph.path((1, 1), (8, 1))
    assert graph.length((1, 1), (3, 3)) == pytest.approx(math.sqrt(8))


def test_an_empty_reachable_floor_has_no_path_and_non_areas_are_refused() -> None:
    graph = RouteGraph(box(0, 0, 1, 1).buffer(-1.0))
    with pytest.raises(NoPathError, match="outside"):
        graph.path((0.5, 0.5), (0.6, 0.6))
    with pytest.raises(ValueError, match="polygonal"):
        RouteGraph(LineString([(0, 0), (1, 1)]))
    with pytest.raises(ValueError, match="simplify"):
        RouteGraph(box(0, 0, 1, 1), simplify=-1.0)


def test_corridor_width_of_a_straight_two_metre_corridor_is_two_metres() -> None:
    corridor = box(0, 0, 20, 2)
    widths = corridor_width(corridor, [[5.0, 1.0], [15.0, 1.0]])
    assert widths.shape == (21,)  # 10 m at 2 samples per metre, both ends
    assert_allclose(widths, 2.0)
    off_centre = corridor_width(corridor, [[5.0, 0.5], [15.0, 0.5]], samples_per_m=1.0)
    assert_allclose(off_centre, 1.0)
    # outside the free floor the width is 0
    assert_allclose(corridor_width(corridor, [[5.0, 1.0], [5.0, 3.0]], 1.0), [2.0, 0.0, 0.0])
    assert_allclose(corridor_width(corridor, [[5.0, 1.0]]), [2.0])
    with pytest.raises(ValueError, match="samples_per_m"):
        corridor_width(corridor, [[5.0, 1.0], [6.0, 1.0]], samples_per_m=0.0)
    with pytest.raises(ValueError, match=r"\(K, 2\)"):
        corridor_width(corridor, [1.0, 2.0, 3.0])


def test_a_hall_with_two_thousand_corners_builds_in_seconds() -> None:
    site = _benchmark_site(quad_segs=2)
    assert 1800 <= len(shapely.get_coordinates(site)) <= 2200
    began = time.perf_counter()
    graph = RouteGraph(site, simplify=0.0)
    assert time.perf_counter() - began < 10.0  # about 0.4 s measured
    path = graph.path((0.5, 0.5), (59.5, 14.5))
    assert site.buffer(1e-6).covers(LineString(path))
    assert _length(path) >= math.dist((0.5, 0.5), (59.5, 14.5))


def test_all_lengths_at_once_are_each_pair_alone() -> None:
    # lengths() joins each point once and searches once from each: the lengths of path().
    rng = np.random.default_rng(7)
    site = _benchmark_site(quad_segs=2)
    graph = RouteGraph(site)
    x0, y0, x1, y1 = site.bounds
    points = rng.uniform((x0, y0), (x1, y1), (60, 2))
    points = points[[graph.region_of(p) is not None for p in points]][:12]
    points = np.vstack([points, points[:1]])  # a point twice: no length between them
    each = np.array([[graph.length(a, b) for b in points] for a in points])
    assert_allclose(graph.lengths(points), each, rtol=1e-12, atol=1e-12)
    assert np.sum(each > 1.001 * np.linalg.norm(points[:, None] - points[None], axis=2)) > 10

    two = RouteGraph(MultiPolygon([box(0, 0, 4, 4), box(6, 0, 10, 4)]))
    with pytest.raises(NoPathError, match="separate regions"):
        two.lengths([(1, 1), (2, 2), (8, 1)])
    with pytest.raises(NoPathError, match=r"the goal \(5.000, 1.000\) is outside"):
        two.lengths([(1, 1), (5, 1)])
