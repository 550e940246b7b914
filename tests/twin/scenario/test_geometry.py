"""Plan geometry: the segment test for many segments and obstacles at once gives what it
gives for each segment and each obstacle alone, and obstacles far from the segments are
rightly left out of it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from twin.scenario import load_scenario
from twin.scenario.geometry import inside_obstacle, obstacles_near, segment_blocked

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
            assert not inside_obstacle(ob, np.vstack([a, b])[:, :2], margin).any()
