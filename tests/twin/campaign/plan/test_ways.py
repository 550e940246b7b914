"""A child's way to a data stop keeps clear of the robots that stand and of the map."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from twin.campaign.plan.clearance import path_clear, robot_fits
from twin.campaign.plan.ways import WAY_CLEARANCE, leg_clear, map_clearance, way_to
from twin.scenario import load_scenario
from twin.scenario.schema import Obstacle

ROOT = Path(__file__).resolve().parents[4]
SPACE = load_scenario(ROOT / "scenarios" / "smoke.toml").space  # x -2..8, y -3..3, a pillar

KEEP = 0.87
"""The distance kept from the parent (its radius, a child's and the margin), m."""


def _nearest(a, b, centre):
    """Least distance of (2,) ``centre`` from the segment a-b, m."""
    a, b, c = (np.asarray(v, dtype=float) for v in (a, b, centre))
    t = np.clip((c - a) @ (b - a) / max(float((b - a) @ (b - a)), 1e-12), 0.0, 1.0)
    return float(np.linalg.norm(a + t * (b - a) - c))


def test_a_clear_straight_way_has_no_corner():
    assert way_to(SPACE, [1.0, 1.0], [4.0, 1.0], [[2.5, -1.0]], [KEEP]) == []


def test_a_robot_on_the_straight_line_is_driven_round_at_the_distance_kept():
    start, goal, parent = np.array([0.0, 0.0]), np.array([5.0, 0.0]), np.array([2.5, 0.1])
    assert not leg_clear(SPACE, start, goal, [parent], [KEEP])
    way = way_to(SPACE, start, goal, [parent], [KEEP])
    assert way is not None
    assert len(way) == 1
    points = [start, *way, goal]
    for a, b in itertools.pairwise(points):
        assert _nearest(a, b, parent) >= KEEP
        assert path_clear(SPACE, a, b, WAY_CLEARANCE)


def test_a_child_beside_a_robot_may_drive_away_from_it_but_not_past_it():
    parent = np.array([2.0, 0.0])
    beside = parent + np.array([0.6, 0.0])  # nearer than KEEP, where its last drive left it
    assert leg_clear(SPACE, beside, [5.0, 0.0], [parent], [KEEP])
    assert not leg_clear(SPACE, beside, [-1.0, 0.0], [parent], [KEEP])


def test_no_way_where_robots_and_walls_close_every_side():
    # A child in the room's corner behind a wall of robots: no corner gets it out.
    robots = [[-1.0, y] for y in np.arange(-3.0, 3.01, 0.5)]
    assert way_to(SPACE, [-1.6, -2.5], [5.0, 0.0], robots, [KEEP] * len(robots)) is None


def test_a_way_into_the_pillar_is_refused():
    assert way_to(SPACE, [4.0, -2.2], [6.5, -2.2], [], []) is None


def test_a_child_that_stopped_against_a_wall_may_drive_away_from_it():
    # Where a render-fidelity drive ended against the north wall (y = 3): the child's centre
    # 0.27 m from it, nearer than a way keeps. It leaves on a way no nearer the wall, to the
    # next stop; a stop in the pillar stays out of reach, and a child in a wall has no way.
    start = np.array([-1.08, 2.73])
    assert map_clearance(SPACE, start) == pytest.approx(0.27)
    assert not path_clear(SPACE, start, start, WAY_CLEARANCE)
    for goal in ([-1.04, -2.52], [3.94, 0.80], [-1.5, 0.0]):
        way = way_to(SPACE, start, goal, [[0.0, 0.0]], [KEEP])
        assert way is not None, goal
        points = [start, *way, np.asarray(goal)]
        assert path_clear(SPACE, points[0], points[1], 0.27 - 1e-6)
        for a, b in itertools.pairwise(points[1:]):
            assert path_clear(SPACE, a, b, WAY_CLEARANCE)
    assert way_to(SPACE, start, [-1.08, 2.9], [], []) is None  # nearer the wall still
    assert way_to(SPACE, start, [6.5, -2.2], [], []) is None
    assert way_to(SPACE, [-1.0, 3.1], [0.0, 0.0], [], []) is None


CRATE = Obstacle(name="crate", center=(2.0, 1.5), size=(1.0, 0.4, 1.0), yaw_deg=30.0)
WITH_CRATE = SPACE.model_copy(update={"obstacles": (*SPACE.obstacles, CRATE)})


@settings(max_examples=200, deadline=None)
@given(st.floats(-2.5, 8.5), st.floats(-3.5, 3.5), st.floats(0.0, 1.0))
def test_the_clearance_of_a_point_is_what_robot_fits_measures(x, y, clearance):
    room = map_clearance(WITH_CRATE, [x, y])
    assume(abs(room - clearance) > 1e-9)  # at the boundary walls and obstacles differ
    assert bool(robot_fits(WITH_CRATE, [[x, y]], clearance)[0]) == (room > clearance)


@settings(max_examples=60, deadline=None)
@given(
    st.floats(-1.5, 7.5),
    st.floats(-2.5, 2.5),
    st.floats(-1.5, 7.5),
    st.floats(-2.5, 2.5),
    st.floats(-1.5, 7.5),
    st.floats(-2.5, 2.5),
)
# Beside the pillar: a way that steps off it to the clearance it stands at, then runs to
# the goal past the pillar's corner, would keep that smaller clearance after the step.
@example(7.0, -2.0, 0.0, 0.0, 0.0, 1.0)
def test_every_way_found_keeps_its_distances(x0, y0, x1, y1, px, py):
    start, goal, parent = np.array([x0, y0]), np.array([x1, y1]), np.array([px, py])
    way = way_to(SPACE, start, goal, [parent], [KEEP])
    if way is None:
        return
    points = [start, *way, goal]
    room = min(KEEP, float(np.linalg.norm(start - parent)))
    # A start nearer the map than a way keeps is left no nearer than it stands.
    clearance = min(WAY_CLEARANCE, map_clearance(SPACE, start) - 1e-9)
    for a, b in itertools.pairwise(points):
        assert _nearest(a, b, parent) >= room - 1e-9
        assert path_clear(SPACE, a, b, clearance)
        room = min(KEEP, float(np.linalg.norm(b - parent)))
        clearance = WAY_CLEARANCE


def test_a_way_round_two_rows_of_robots_bends_as_often_as_it_must():
    # Robots closing the room from the south up to y = 0.5 at x = 1.5, and from the north
    # down to y = -0.5 at x = 3.5: no way with one corner; the shortest way on the floor
    # round them winds between the rows, each leg clear of the map and every robot.
    robots = [[1.5, y] for y in np.arange(-3.0, 0.51, 0.5)]
    robots += [[3.5, y] for y in np.arange(-0.5, 3.01, 0.5)]
    keep = [0.79] * len(robots)
    start, goal = np.array([0.0, 0.0]), np.array([5.0, 0.5])
    way = way_to(SPACE, start, goal, robots, keep)
    assert way is not None
    assert len(way) >= 2
    for a, b in itertools.pairwise([start, *way, goal]):
        assert leg_clear(SPACE, a, b, robots, keep)
        for r in robots:
            assert _nearest(a, b, r) >= 0.79
