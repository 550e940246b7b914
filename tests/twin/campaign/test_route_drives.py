"""A child's drives along the route in a CPS leg: round the robots that stand where the
straight drive to the next corner passes one, straight on where nothing stands in the way.

A leg can start at a route's turn where the parent stands, and a child that left the route
for a camera's data comes back to the route's next corner past it. Placed at the geometric
fidelity such a drive goes through the parent unseen; driven at the render fidelity it
pushes the parent off its station (or stops against it) and the campaign aborts.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

import twin.sim  # noqa: F401  (headless rendering is configured before MuJoCo loads)
from tests.twin.campaign.drive_goals import recorded_goals
from twin.campaign import Campaign
from twin.campaign.plan.clearance import path_clear
from twin.campaign.plan.stop import Stop
from twin.campaign.plan.ways import WAY_CLEARANCE
from twin.campaign.strategy import Move
from twin.scenario import load_scenario
from twin.scenario.schema import Obstacle
from twin.sim.rig import build_sim_rig
from twin.sim.world import build_world

SMOKE = Path(__file__).resolve().parents[3] / "scenarios" / "smoke.toml"


class _Quiet:
    def record(self, topic: str, record: object, timestamp: float) -> None:
        pass


def _nearest(a, b, centre) -> float:
    t = np.clip((centre - a) @ (b - a) / max(float((b - a) @ (b - a)), 1e-12), 0.0, 1.0)
    return float(np.linalg.norm(a + t * (b - a) - centre))


@pytest.fixture
def drives(monkeypatch):
    """The smoke room's rig at the geometric fidelity (the parent stands at (0, 0), child2
    at (1.5, -1.5)) with child1 put at (-1.5, 0.3), west of the parent; the goals of
    child1's drives from then on are recorded."""
    sc = load_scenario(SMOKE)
    sim = build_sim_rig(build_world(sc), "geometric", seed=5)
    travel = Campaign(sim.rig, sc, _Quiet()).travel
    child = sim.rig.children["child1"]
    assert child.drive_to(np.array([-1.5, 0.3])).reached
    goals = recorded_goals(monkeypatch, child)
    yield sim, travel, goals
    sim.close()


def _move(corner, stop) -> Move:
    stop = np.asarray(stop, dtype=float)
    return Move("child1", Stop(stop, 0.0), (np.asarray(corner, dtype=float),), stop, stop)


def test_a_child_back_to_the_route_drives_round_the_parent_at_its_corner(drives):
    sim, travel, goals = drives
    start = sim.rig.children["child1"].odometry().pose[:2].copy()
    corner, stop = np.array([1.6, 0.0]), np.array([2.5, 0.8])
    robots, keep = travel.standing_robots("child1")
    parent = travel.cps.parent.translation[:2]
    assert _nearest(start, corner, parent) < keep[0]  # straight on goes through the parent
    assert travel.drive_along(sim.rig.children["child1"], _move(corner, stop))
    truth = sim.frame.pose(sim.world.robot_pose("child1"))
    assert len(goals) == 3  # a corner round the parent, the route's corner, the stop
    np.testing.assert_allclose(goals[1:], [corner, stop])
    for a, b in itertools.pairwise([start, *goals]):
        for centre, room in zip(robots, keep, strict=True):
            assert _nearest(a, b, centre) >= min(room, float(np.linalg.norm(a - centre))) - 1e-9
    # At its stop, give or take three drives' stopping errors (0.02 m per axis, and the
    # heading's carried over a few metres).
    assert np.linalg.norm(truth[:2] - stop) < 0.3


def test_a_child_with_nothing_in_its_way_drives_the_route_as_planned(drives):
    sim, travel, goals = drives
    corner, stop = np.array([-1.5, 2.0]), np.array([0.5, 2.5])  # north of the parent
    assert travel.drive_along(sim.rig.children["child1"], _move(corner, stop))
    np.testing.assert_allclose(goals, [corner, stop])


def test_a_route_corner_where_the_parent_stands_is_passed_by(drives):
    # A leg that starts at the route's turn: the child's first corner is the parent's own
    # station. Driven to, the child is put onto the parent, pushed off and turned, and its
    # own estimate is then off by what the push did.
    sim, travel, goals = drives
    parent = travel.cps.parent.translation[:2].copy()
    stop = np.array([1.0, 1.2])
    robots, keep = travel.standing_robots("child1")
    assert travel.drive_along(sim.rig.children["child1"], _move(parent, stop))
    assert all(np.linalg.norm(g - parent) >= keep[0] for g in goals[:-1])
    np.testing.assert_allclose(goals[-1], stop)
    start = np.array([-1.5, 0.3])
    for a, b in itertools.pairwise([start, *goals]):
        for centre, room in zip(robots, keep, strict=True):
            assert _nearest(a, b, centre) >= min(room, float(np.linalg.norm(a - centre))) - 1e-9
    # Where its estimate says, to a few drives' stopping errors (0.02 m per axis), and
    # heading as it believes (no push turned it).
    truth = sim.frame.pose(sim.world.robot_pose("child1"))
    believed = sim.rig.children["child1"].odometry().pose
    assert np.linalg.norm(truth[:2] - believed[:2]) < 0.15
    assert abs((truth[2] - believed[2] + np.pi) % (2 * np.pi) - np.pi) < np.radians(5.0)


def test_the_drive_past_a_corner_passed_by_goes_round_the_map(monkeypatch):
    # The straight line from the child to its stop, the corner at the parent passed by,
    # keeps clear of the robots but runs through a post that the route's turn went round.
    sc = load_scenario(SMOKE)
    post = Obstacle(name="post", center=(-0.7, -0.62), size=(0.3, 0.3, 2.0))
    space = sc.space.model_copy(update={"obstacles": (*sc.space.obstacles, post)})
    sc = sc.model_copy(update={"space": space})
    sim = build_sim_rig(build_world(sc), "geometric", seed=5)
    travel = Campaign(sim.rig, sc, _Quiet()).travel
    child = sim.rig.children["child1"]
    assert child.drive_to(np.array([-1.5, 0.3])).reached
    start, stop = child.odometry().pose[:2].copy(), np.array([0.5, -2.0])
    parent = travel.cps.parent.translation[:2].copy()
    robots, keep = travel.standing_robots("child1")
    assert all(_nearest(start, stop, c) >= k for c, k in zip(robots, keep, strict=True))
    assert not path_clear(sc.space, start, stop, WAY_CLEARANCE)
    goals = recorded_goals(monkeypatch, child)
    assert travel.drive_along(child, _move(parent, stop))
    sim.close()
    assert len(goals) >= 2  # round the post, then the stop
    np.testing.assert_allclose(goals[-1], stop)
    for a, b in itertools.pairwise([start, *goals]):
        assert path_clear(sc.space, a, b, WAY_CLEARANCE - 1e-6)
