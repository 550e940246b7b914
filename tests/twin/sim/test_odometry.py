"""Wheel odometry: against the simulated truth with its random and systematic errors off
(what is left is the model's own kinematics, skid-steer slip, which odometry must match),
and its error model, statistically: the spread of the errors of many robots driving the
same wheel turns is what OdometrySpec says."""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest

from calib.rotation import wrap_angle
from twin.scenario import Scenario, scenario_from_dict
from twin.scenario.robots import PIONEER3DX, OdometrySpec
from twin.sim.odometry import WheelOdometry
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


# -- the error model, statistically ----------------------------------------------------------
# Many robots drive the same wheel turns; each draws its own errors. The spread of their
# odometry errors must be what OdometrySpec says, to first order in the (small) errors. With
# N robots a sample variance has a relative standard error of sqrt(2 / N): 2.6 % for
# N = 3000. Each variance is held to 4.5 standard errors (12 %, two-sided: a false alarm
# once in 150 000 per check, fewer than 1e-4 for the whole of this section); a standard
# deviation 12 % off in the model or the code fails it.

ROBOTS = 3000
BAND = 4.5 * np.sqrt(2.0 / ROBOTS)
RADIUS, TRACK = PIONEER3DX.wheel_radius, PIONEER3DX.effective_track


def drive(spec: OdometrySpec, steps: int, left: float, right: float) -> np.ndarray:
    """(ROBOTS, 3) final (x, y, yaw) of robots that each turn their wheels by ``left`` and
    ``right`` (rad) in each of ``steps`` updates from (0, 0, 0), every robot with its own
    draws."""
    out = np.empty((ROBOTS, 3))
    for i, seed in enumerate(np.random.SeedSequence(20240).spawn(ROBOTS)):
        odo = WheelOdometry(RADIUS, TRACK, spec, np.random.default_rng(seed))
        for _ in range(steps):
            odo.update(left, right)
        out[i] = odo.pose
    return out


def variance_ratio(values: np.ndarray, expected_variance: float) -> float:
    """Mean square about zero (the truth) over the model's variance."""
    return float(np.mean(values**2) / expected_variance)


RANDOM_ONLY = OdometrySpec(wheel_scale_sigma=0.0, track_sigma=0.0)
SYSTEMATIC_ONLY = OdometrySpec(distance_noise=0.0, heading_noise=0.0)


def test_random_error_of_a_straight_run_grows_as_the_model_says():
    # K steps of d metres straight ahead. Each step adds distance noise s_d sqrt(d) and
    # heading noise s_h sqrt(d); the heading error of step j turns the remaining (K - j)
    # steps and half of its own, so to first order
    #   var(along) = s_d^2 K d,  var(yaw) = s_h^2 K d,
    #   var(across) = s_h^2 d^3 sum_{m=0}^{K-1} (m + 1/2)^2 = s_h^2 d^3 (K^3 / 3 - K / 12),
    #   cov(across, yaw) = s_h^2 d^2 K^2 / 2.
    steps, d = 10, 0.5
    pose = drive(RANDOM_ONLY, steps, d / RADIUS, d / RADIUS)
    s_d, s_h = RANDOM_ONLY.distance_noise, RANDOM_ONLY.heading_noise
    along, across, yaw = pose[:, 0] - steps * d, pose[:, 1], pose[:, 2]
    ratios = {
        "along": variance_ratio(along, s_d**2 * steps * d),
        "yaw": variance_ratio(yaw, s_h**2 * steps * d),
        "across": variance_ratio(across, s_h**2 * d**3 * (steps**3 / 3 - steps / 12)),
        "across x yaw": float(np.mean(across * yaw) / (s_h**2 * d**2 * steps**2 / 2)),
    }
    assert all(abs(r - 1.0) < BAND for r in ratios.values()), (ratios, BAND)


def test_random_error_of_a_turn_in_place_grows_with_the_wheels_travel():
    # Turning in place, each wheel travels (track / 2) per radian: over a quarter turn the
    # model's "travelled" is pi / 4 * track, which sets the heading noise, and the distance
    # noise moves the robot along its heading: var(x) + var(y) = s_d^2 pi / 4 * track.
    steps = 10
    wheel = (np.pi / 2) * (TRACK / 2) / RADIUS / steps
    pose = drive(RANDOM_ONLY, steps, -wheel, wheel)
    travelled = np.pi / 4 * TRACK
    s_d, s_h = RANDOM_ONLY.distance_noise, RANDOM_ONLY.heading_noise
    yaw = np.array([wrap_angle(y - np.pi / 2) for y in pose[:, 2]])
    ratios = {
        "yaw": variance_ratio(yaw, s_h**2 * travelled),
        # The mean of x^2 + y^2 has a relative standard error below sqrt(2 / N) too.
        "position": variance_ratio(np.hypot(pose[:, 0], pose[:, 1]), s_d**2 * travelled),
    }
    assert all(abs(r - 1.0) < BAND for r in ratios.values()), (ratios, BAND)


def test_systematic_errors_are_drawn_once_per_robot():
    # Wheel radii off by s_w each, the track by s_t, drawn once: the error of a straight run
    # grows with the distance (not its square root), along = L (e_l + e_r) / 2 and
    # yaw = L (e_r - e_l) / track; a quarter turn in place is off by
    # pi / 2 ((e_l + e_r) / 2 - e_t). One metre keeps the second-order part (the yaw drift
    # bending the path, L yaw^2 / 6) below 1e-4 of the variance; over 5 m it adds 10 %.
    steps, d = 5, 0.2
    s_w, s_t = SYSTEMATIC_ONLY.wheel_scale_sigma, SYSTEMATIC_ONLY.track_sigma
    length = steps * d
    pose = drive(SYSTEMATIC_ONLY, steps, d / RADIUS, d / RADIUS)
    wheel = (np.pi / 2) * (TRACK / 2) / RADIUS / steps
    turn = drive(SYSTEMATIC_ONLY, steps, -wheel, wheel)
    ratios = {
        "along": variance_ratio(pose[:, 0] - length, length**2 * s_w**2 / 2),
        "yaw": variance_ratio(pose[:, 2], 2 * length**2 * s_w**2 / TRACK**2),
        "turn": variance_ratio(turn[:, 2] - np.pi / 2, (np.pi / 2) ** 2 * (s_w**2 / 2 + s_t**2)),
    }
    assert all(abs(r - 1.0) < BAND for r in ratios.values()), (ratios, BAND)


def test_the_world_draws_each_robots_odometry_errors_from_the_scenarios_model():
    # Reset with many seeds: the believed wheel radii and track of the three robots spread
    # as the scenario's model says (6 radii and 3 tracks a seed).
    spec = OdometrySpec(wheel_scale_sigma=0.004, track_sigma=0.02)
    world = build_world(noiseless())
    # A world takes its model from its scenario (here every error off).
    assert {o.spec for o in world.driving.odometry.values()} == {OdometrySpec(0.0, 0.0, 0.0, 0.0)}
    radii, tracks = [], []
    for seed in range(ROBOTS // 3):
        world.driving.reset(seed, spec)
        for name, odo in world.driving.odometry.items():
            platform = world.robots[name].platform
            radii += [odo.radius_left / platform.wheel_radius - 1.0,
                      odo.radius_right / platform.wheel_radius - 1.0]  # fmt: skip
            tracks.append(odo.track / platform.effective_track - 1.0)
            assert odo.spec == spec
    assert abs(variance_ratio(np.array(radii), spec.wheel_scale_sigma**2) - 1) < BAND
    assert abs(variance_ratio(np.array(tracks), spec.track_sigma**2) - 1) < BAND
    # The two sides of a robot are drawn independently.
    left, right = np.array(radii[0::2]), np.array(radii[1::2])
    assert abs(np.mean(left * right)) / spec.wheel_scale_sigma**2 < BAND
