"""Wheel odometry against the simulated truth, with its random and systematic errors off:
what is left is the model's own kinematics (skid-steer slip), which odometry must match."""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest

from calib.rotation import wrap_angle
from twin.scenario import Scenario, scenario_from_dict
from twin.sim.world import build_world

from .helpers import scenario


@cache
def noiseless() -> Scenario:
    """The smoke scenario with every odometry error set to zero."""
    raw = scenario("smoke").model_dump(exclude={"source"})
    raw["noise"]["odometry"] = {k: 0.0 for k in raw["noise"]["odometry"]}
    return scenario_from_dict(raw)


@pytest.mark.parametrize("robot", ["parent", "child1"])
@pytest.mark.parametrize("turn_deg", [90.0, -90.0])
def test_a_90_deg_turn_in_place_leaves_odometry_on_the_true_heading(robot, turn_deg):
    world = build_world(noiseless())
    start = world.robot_pose(robot)
    result = world.drive_to(robot, start[:2], goal_yaw=start[2] + math.radians(turn_deg))
    assert result.status == "reached", result
    turned = wrap_angle(result.pose[2] - start[2])
    assert turned == pytest.approx(math.radians(turn_deg), abs=math.radians(1.0))
    error = wrap_angle(world.driving.odometry[robot].pose[2] - result.pose[2])
    assert abs(error) < math.radians(1.5), math.degrees(error)


@pytest.mark.parametrize("robot", ["parent", "child1"])
def test_odometry_follows_a_straight_line(robot):
    world = build_world(noiseless())
    start = world.robot_pose(robot)
    result = world.drive_to(robot, start[:2] + np.array([4.0, 0.0]))
    assert result.status == "reached", result
    odo = world.driving.odometry[robot].pose
    assert np.linalg.norm(odo[:2] - result.pose[:2]) < 0.02  # 0.5 % of 4 m
    assert abs(wrap_angle(odo[2] - result.pose[2])) < math.radians(0.2)
    assert world.driving.odometry[robot].distance == pytest.approx(4.0, abs=0.02)
