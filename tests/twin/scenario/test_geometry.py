"""Plan geometry: the segment test for many segments and obstacles at once gives what it
gives for each segment and each obstacle alone, and obstacles far from the segments are
rightly left out of it; the footprint tests, rectangles and polyline points that shapely
computes agree with their definitions (in the obstacle's own frame, along each segment)."""

from __future__ import annotations

import math
from pathlib import Path
from unittest import mock

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from twin.scenario import geometry, load_scenario
from twin.scenario.geometry import (
    BROADCAST_PAIRS,
    inside_obstacles,
    obstacles_near,
    polyline_points,
    rectangle,
    segment_blocked,
)
from twin.scenario.schema import Obstacle

HALL = Path(__file__).resolve().parents[3] / "scenarios" / "paper_hall.toml"


@pytest.fixture(scope="module")
def space():
    return load_scenario(HALL).space


point = st.tuples(st.floats(-8.0, 52.0), st.floats(-1.6, 13.4), st.floats(-0.4, 7.6))


@settings(max_examples=50, deadline=None)
@given(segments=st.lists(st.tuples(point, point), min_size=1, max_size=20))
def test_segments_in_a_batch_are_each_alone(space, segments):
    a = np.array([s[0] for s in segments])
    b = np.array([s[1] for s in segments])
    batch = segment_blocked(space, a, b)
    assert batch.shape == (len(a),)
    alone = [bool(segment_blocked(space, p, q)[0]) for p, q in zip(a, b, strict=True)]
    assert [bool(x) for x in batch] == alone


def test_all_obstacles_are_each_obstacle_alone(space):
    rng = np.random.default_rng(4)
    lo, hi = np.array([-8.0, -1.6, -0.4]), np.array([52.0, 13.4, 7.6])
    a, b = rng.uniform(lo, hi, (5000, 3)), rng.uniform(lo, hi, (5000, 3))
    b[:500, 0] = a[:500, 0]  # segments parallel to a side of the boxes
    b[500:1000, 2] = a[500:1000, 2]
    each = [segment_blocked(space, a, b, (ob,)) for ob in space.obstacles]
    blocked = segment_blocked(space, a, b)
    assert np.array_equal(blocked, np.any(each, axis=0))
    assert 0.2 < blocked.mean() < 0.8


def test_a_segment_through_a_box_is_blocked_and_one_above_is_not(space):
    island = next(ob for ob in space.obstacles if ob.name == "island")
    x, y = island.center
    top = space.floor_z + island.size[2]
    assert segment_blocked(space, [x - 10, y, 0.0], [x + 10, y, 0.0])[0]
    assert not segment_blocked(space, [x - 10, y, top + 0.1], [x + 10, y, top + 0.1])[0]
    assert not segment_blocked(space, np.zeros((0, 3)), np.zeros((0, 3))).size


def test_a_margin_keeps_segments_off_a_boxs_sides_and_top(space):
    island = next(ob for ob in space.obstacles if ob.name == "island")
    x, y = island.center
    south = y - 0.5 * island.size[1]
    top = space.floor_z + island.size[2]
    grazing = ([x - 10, south - 0.05, 0.5], [x + 10, south - 0.05, 0.5])  # 5 cm off its side
    over = ([x - 10, y, top + 0.05], [x + 10, y, top + 0.05])  # 5 cm over its top
    for a, b in (grazing, over):
        assert not segment_blocked(space, a, b)[0]
        assert not segment_blocked(space, a, b, margin=0.04)[0]
        assert segment_blocked(space, a, b, margin=0.06)[0]


@settings(max_examples=50, deadline=None)
@given(
    segments=st.lists(st.tuples(point, point), min_size=1, max_size=20),
    margin=st.floats(0.0, 0.5),
)
def test_only_obstacles_near_the_segments_can_block_them(space, segments, margin):
    a = np.array([s[0] for s in segments])
    b = np.array([s[1] for s in segments])
    near = obstacles_near(space.obstacles, np.vstack([a, b])[:, :2], margin)
    every = segment_blocked(space, a, b, margin=margin)
    if near:
        np.testing.assert_array_equal(segment_blocked(space, a, b, near, margin), every)
    else:
        assert not every.any()
    for ob in space.obstacles:
        if ob not in near:
            assert not inside_obstacles((ob,), np.vstack([a, b])[:, :2], margin).any()


@settings(max_examples=30, deadline=None)
@given(
    boxes=st.lists(
        st.tuples(
            st.floats(-20.0, 20.0),
            st.floats(-20.0, 20.0),
            st.floats(0.05, 6.0),
            st.floats(0.05, 6.0),
            st.floats(0.1, 4.0),
            st.sampled_from([0.0, 0.0, 90.0, 30.0, -135.0]),
        ),
        min_size=1,
        max_size=40,
    ),
    margin=st.sampled_from([0.0, 0.05, 0.3]),
    seed=st.integers(0, 2**32 - 1),
)
def test_the_plan_and_slab_tests_are_the_slab_test_of_every_pair(space, boxes, margin, seed):
    # Shapely's plan test where a box is taller than the segment, the slab test only for the
    # pairs that need it: the answer of the slab test of every segment against every box,
    # also for vertical segments and segments that start over a box. A segment along a side
    # touches its face, which blocks it; the slab test, in the box's own frame, may round
    # the side off by a bit and let it pass.
    obstacles = tuple(
        Obstacle(name=f"b{k}", center=(x, y), size=(sx, sy, h), yaw_deg=yaw)
        for k, (x, y, sx, sy, h, yaw) in enumerate(boxes)
    )
    # Segments up to 5 m high (over some boxes) and segments below every box's top (each
    # box then blocks wherever the segment crosses its footprint: the union's test).
    rng = np.random.default_rng(seed)
    for top in (5.0, 0.1):
        lo = np.array([-25.0, -25.0, space.floor_z])
        hi = np.array([25.0, 25.0, space.floor_z + top])
        a, b = rng.uniform(lo, hi, (300, 3)), rng.uniform(lo, hi, (300, 3))
        first = obstacles[0]
        half = 0.5 * first.size[0] + margin
        a[:50, 0] = b[:50, 0] = first.center[0] + half  # along the first box's side at yaw 0
        b[50:100, :2] = a[50:100, :2]  # vertical segments
        a[100:150, :2] = first.center  # starting over the first box
        got = segment_blocked(space, a, b, obstacles, margin)
        boxes_ = geometry._box_arrays(space.floor_z, obstacles, margin)
        dense = geometry._slab_hits(*(x[:, None] for x in boxes_), a, b).any(axis=0)
        np.testing.assert_array_equal(got[50:], dense[50:])
        assert got[:50][dense[:50]].all()
        if first.yaw == 0.0 and top <= first.size[2]:
            # Below the first box's top, along its side: blocked where it runs beside it.
            cy, hy = first.center[1], 0.5 * first.size[1] + margin
            y0, y1 = np.minimum(a[:50, 1], b[:50, 1]), np.maximum(a[:50, 1], b[:50, 1])
            beside = (y0 < cy + hy - 1e-9) & (y1 > cy - hy + 1e-9)
            assert got[:50][beside].all()
    # Below every box's top, a segment that starts over the first box is blocked: the test
    # has blocked segments to compare (above, a small box may meet none of them).
    assert dense[100:150].all()


def test_a_segment_along_a_face_below_the_top_is_blocked(space):
    # 4.0 + 0.025 m in W is 4.025; in the box's frame 4.025 - 4.0 rounds above 0.025, where
    # the slab test put it outside the box.
    post = Obstacle(name="post", center=(4.0, 0.0), size=(0.05, 1.0, 1.0))
    z = space.floor_z + 0.5
    along = segment_blocked(space, [4.025, -2.0, z], [4.025, 2.0, z], (post,))
    beside = segment_blocked(space, [4.0251, -2.0, z], [4.0251, 2.0, z], (post,))
    over = segment_blocked(space, [4.025, -2.0, z + 1.0], [4.025, 2.0, z + 1.0], (post,))
    assert along.tolist() == [True]
    assert beside.tolist() == over.tolist() == [False]


def _box_frame(obstacle: Obstacle, points: np.ndarray) -> np.ndarray:
    """(N, 2) floor points in the obstacle's own frame (origin at its centre, axes along its
    sides), m."""
    c, s = math.cos(obstacle.yaw), math.sin(obstacle.yaw)
    d = points - np.asarray(obstacle.center)
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])


def _half(obstacle: Obstacle, margin: float) -> np.ndarray:
    """(2,) half sides of the footprint grown by ``margin``, m."""
    return np.array([0.5 * obstacle.size[0] + margin, 0.5 * obstacle.size[1] + margin])


obstacles = st.builds(
    lambda x, y, sx, sy, yaw: Obstacle(name="box", center=(x, y), size=(sx, sy, 1.0), yaw_deg=yaw),
    st.floats(-100.0, 100.0),
    st.floats(-100.0, 100.0),
    st.floats(0.01, 30.0),
    st.floats(0.01, 30.0),
    st.floats(-360.0, 360.0),
)
margins = st.floats(0.0, 1.0)


@settings(max_examples=200, deadline=None)
@given(obstacle=obstacles, margin=margins, seed=st.integers(0, 2**32 - 1))
def test_inside_obstacle_is_the_box_in_its_own_frame(obstacle, margin, seed):
    # Points in and around the footprint, clear of its sides by more than 1e-9 m.
    rng = np.random.default_rng(seed)
    half = _half(obstacle, margin)
    local = rng.uniform(-1.5, 1.5, (300, 2)) * half
    c, s = math.cos(obstacle.yaw), math.sin(obstacle.yaw)
    points = local @ np.array([[c, s], [-s, c]]) + np.asarray(obstacle.center)
    q = np.abs(_box_frame(obstacle, points))
    clear = np.all(np.abs(q - half) > 1e-9, axis=1)
    inside = np.all(q <= half, axis=1)
    found = inside_obstacles((obstacle,), points, margin)[0]
    np.testing.assert_array_equal(found[clear], inside[clear])
    assert 0 < inside[clear].sum() < clear.sum()


@settings(max_examples=200, deadline=None)
@given(
    obstacle=obstacles,
    margin=margins,
    side=st.sampled_from([(1, 0), (-1, 0), (0, 1), (0, -1)]),
    along=st.floats(-0.99, 0.99),
)
def test_an_axis_aligned_footprint_holds_its_sides_to_the_bit(obstacle, margin, side, along):
    # An axis-aligned footprint's sides lie where |point - centre| <= half side puts them,
    # exactly: robots are placed at exactly a clearance from a side, and a side rounded by
    # one bit turns such a place from blocked to free.
    ob = obstacle.model_copy(update={"yaw_deg": 0.0})
    half = _half(ob, margin)
    k = 0 if side[0] else 1  # the axis across the side
    edge = np.array(ob.center)
    edge[1 - k] += along * half[1 - k]
    edge[k] += side[k] * half[k]
    # The side itself, and the floats next to it either way.
    points = np.repeat(edge[None], 3, axis=0)
    points[1, k] = np.nextafter(edge[k], -np.inf)
    points[2, k] = np.nextafter(edge[k], np.inf)
    q = np.abs(points - np.asarray(ob.center))
    expected = np.all(q <= half, axis=1)
    np.testing.assert_array_equal(inside_obstacles((ob,), points, margin)[0], expected)
    assert expected.sum() >= 1


def test_a_place_at_exactly_a_clearance_from_the_island_is_blocked(space):
    # The island's south side is at y = 0.7 m: a place at y = 0.35 m is 0.35 m from it,
    # which the formation's clearance of 0.35 m counts as blocked (a footprint grown in W,
    # 2.0 - (1.3 + 0.35), would round its side to just above 0.35).
    island = next(ob for ob in space.obstacles if ob.name == "island")
    assert inside_obstacles((island,), [[26.0, 0.35]], 0.35)[0]
    assert not inside_obstacles((island,), [[26.0, np.nextafter(0.35, 0.0)]], 0.35)[0]


@settings(max_examples=50, deadline=None)
@given(
    footprints=st.lists(obstacles, min_size=1, max_size=6),
    margin=margins,
    seed=st.integers(0, 2**32 - 1),
)
def test_many_points_at_once_are_each_point_alone(footprints, margin, seed):
    # Beyond BROADCAST_PAIRS pairs only the points within a footprint's bounding box are
    # handed to shapely: the answer is the one each point gets alone, on the sides too.
    rng = np.random.default_rng(seed)
    obs = tuple(ob.model_copy(update={"yaw_deg": 0.0}) for ob in footprints[::2])
    obs += tuple(footprints[1::2])
    points = rng.uniform(-110.0, 110.0, (BROADCAST_PAIRS + 50, 2))
    centres = np.array([ob.center for ob in obs])
    points[::2] = centres[rng.integers(len(obs), size=len(points[::2]))]
    points[::2] += rng.uniform(-15.0, 15.0, points[::2].shape)
    corners = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1], [1, 0], [0, 1], [-1, 0], [0, -1]])
    sides = [np.asarray(ob.center) + corners * _half(ob, margin) for ob in obs]
    points = np.vstack([points, *sides])
    together = inside_obstacles(obs, points, margin)
    alone = np.column_stack([inside_obstacles(obs, p[None], margin)[:, 0] for p in points])
    assert together.shape == (len(obs), len(points))
    np.testing.assert_array_equal(together, alone)
    # Beyond TREE_PAIRS the pairs come from the footprints' search tree: the same answer.
    with mock.patch.object(geometry, "TREE_PAIRS", 0):
        np.testing.assert_array_equal(inside_obstacles(obs, points, margin), together)


def test_no_obstacles_and_no_points():
    post = Obstacle(name="post", center=(0.0, 0.0), size=(0.1, 0.1, 1.0))
    assert inside_obstacles((), [[0.0, 0.0]]).shape == (0, 1)
    assert inside_obstacles((post,), np.zeros((0, 2))).shape == (1, 0)
    assert obstacles_near((post,), np.zeros((0, 2))) == ()
    assert obstacles_near((), [[0.0, 0.0]]) == ()


def test_a_post_is_near_a_point_in_the_corner_of_its_clearance():
    # The clearance grows a footprint into a larger rectangle, whose corners reach farther
    # than the footprint's enclosing circle grown by the clearance.
    post = Obstacle(name="post", center=(0.0, 0.0), size=(0.01, 0.01, 2.0))
    corner = [[0.28, 0.28]]  # 0.40 m from the post's centre, within 0.29 m on each axis
    assert inside_obstacles((post,), corner, 0.29)[0]
    assert obstacles_near((post,), corner, 0.29) == (post,)
    assert obstacles_near((post,), [[0.31, 0.0]], 0.29) == ()


@settings(max_examples=100, deadline=None)
@given(obstacle=obstacles)
def test_a_rectangle_has_the_corners_of_the_box(obstacle):
    foot = rectangle(obstacle.center, obstacle.size[:2], obstacle.yaw)
    hx, hy = 0.5 * obstacle.size[0], 0.5 * obstacle.size[1]
    c, s = math.cos(obstacle.yaw), math.sin(obstacle.yaw)
    local = np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]])
    corners = local @ np.array([[c, s], [-s, c]]) + np.asarray(obstacle.center)
    found = shapely.get_coordinates(foot)[:-1]
    # The same four corners, whatever the ring's first one.
    for corner in corners:
        assert np.min(np.linalg.norm(found - corner, axis=1)) < 1e-12 * (1.0 + hx + hy + 100.0)
    assert foot.is_valid
    assert foot.area == pytest.approx(obstacle.size[0] * obstacle.size[1], rel=1e-12)


waypoint = st.tuples(st.floats(-50.0, 50.0), st.floats(-50.0, 50.0))


@settings(max_examples=200, deadline=None)
@given(
    waypoints=st.lists(waypoint, min_size=2, max_size=8),
    spacing=st.floats(0.01, 5.0),
)
def test_polyline_points_cut_each_segment_into_equal_parts(waypoints, spacing):
    p = np.array(waypoints)
    points, segment = polyline_points(p, spacing)
    assert points.shape == (len(segment), 2)
    assert np.all(np.diff(segment) >= 0)
    if np.all(p == p[0]):
        np.testing.assert_array_equal(points, p[:1])
        return
    for i in range(len(p) - 1):
        on = points[segment == i]
        if np.all(p[i + 1] == p[i]):  # no part of its own: its point is a neighbour's end
            assert len(on) == 0
            continue
        length = float(np.linalg.norm(p[i + 1] - p[i]))
        parts = length / spacing
        # The straightforward definition: ceil(length / spacing) equal parts.
        if abs(parts - round(parts)) > 1e-9:
            assert len(on) == math.ceil(parts) + 1
        expected = p[i] + np.linspace(0.0, 1.0, len(on))[:, None] * (p[i + 1] - p[i])
        rounding = 1e-12 * (1.0 + float(np.abs(p).max()))
        np.testing.assert_allclose(on, expected, rtol=0.0, atol=rounding)
        np.testing.assert_array_equal(on[[0, -1]], p[[i, i + 1]])
        assert np.all(np.linalg.norm(np.diff(on, axis=0), axis=1) <= spacing + rounding)


def test_polyline_points_of_a_polyline_that_stays_put():
    points, segment = polyline_points([[1.0, 2.0], [1.0, 2.0]], 0.1)
    np.testing.assert_array_equal(points, [[1.0, 2.0]])
    np.testing.assert_array_equal(segment, [0])
    with pytest.raises(ValueError, match="at least 2 waypoints"):
        polyline_points([[1.0, 2.0]], 0.1)
