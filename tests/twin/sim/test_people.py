"""People walking through the space: their path, and their bodies in the world."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from twin.scenario.schema import Person
from twin.sim.people import person_pose
from twin.sim.world import build_world

from .helpers import scenario

WALKER = Person(name="walker", waypoints=((0.0, 0.0), (4.0, 0.0), (4.0, 3.0)), speed=1.0)


def test_walks_the_path_to_its_end_and_back():
    xy, heading = person_pose(WALKER, 0.0)
    np.testing.assert_allclose(xy, [0.0, 0.0])
    assert heading == pytest.approx(0.0)
    xy, heading = person_pose(WALKER, 5.5)  # 1.5 m up the second leg
    np.testing.assert_allclose(xy, [4.0, 1.5], atol=1e-12)
    assert heading == pytest.approx(math.pi / 2)
    xy, heading = person_pose(WALKER, 8.0)  # 1 m back from the end
    np.testing.assert_allclose(xy, [4.0, 2.0], atol=1e-12)
    assert heading == pytest.approx(-math.pi / 2)
    xy, _ = person_pose(WALKER, 14.0)  # back at the start: one round trip is 14 m
    np.testing.assert_allclose(xy, [0.0, 0.0], atol=1e-12)


def test_start_offset_and_repeated_waypoints():
    p = Person(name="p", waypoints=((0.0, 0.0), (0.0, 0.0), (2.0, 0.0)), start_offset=0.5)
    np.testing.assert_allclose(person_pose(p, 0.0)[0], [0.5, 0.0])


@settings(max_examples=200, deadline=None)
@given(t=st.floats(0.0, 1000.0), dt=st.floats(1e-4, 0.5))
def test_walks_continuously_at_its_speed(t, dt):
    a, _ = person_pose(WALKER, t)
    b, _ = person_pose(WALKER, t + dt)
    assert np.linalg.norm(b - a) <= WALKER.speed * dt + 1e-9


def test_people_in_the_world_move_and_block_lines_of_sight():
    sc = scenario("smoke")
    person = Person(name="walker", waypoints=((3.0, -2.0), (3.0, 2.0)), speed=1.0)
    world = build_world(sc.model_copy(update={"people": (person,)}))
    body = world.model.body("walker")
    assert world.model.body_mocapid[body.id] >= 0
    # At t = 0 the person stands at (3, -2): a line along y = -2 through it is blocked.
    assert not world.sensing.line_of_sight([1.0, -2.0, 0.5], [5.0, -2.0, 0.5])
    assert world.sensing.line_of_sight([1.0, 1.9, 0.5], [5.0, 1.9, 0.5])
    world.run(4.0)  # now near (3, 2)
    np.testing.assert_allclose(world.data.xpos[body.id][:2], [3.0, 2.0], atol=0.05)
    assert world.sensing.line_of_sight([1.0, -2.0, 0.5], [5.0, -2.0, 0.5])
    assert not world.sensing.line_of_sight([1.0, 1.9, 0.5], [5.0, 1.9, 0.5])
    # No contacts: robots walk through people.
    assert world.driving.collisions == []
