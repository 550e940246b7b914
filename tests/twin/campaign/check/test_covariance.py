"""The check data's joint covariance: each stop's own block, the parent's pose error
shared by everything measured from one fix, and a child's marker survey error shared by
its stops."""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.testing import assert_allclose

from calib.rotation import rot_z
from twin.campaign.check.covariance import leds_covariance, parent_jacobian, pixel_noise
from twin.campaign.check.gathering import CheckPoint
from twin.campaign.records import ParentFix
from twin.instruments.marker import MarkerAssembly
from twin.instruments.marker_pose import survey_loading

from .synthetic import PARENT_COV, draw_points, stop_covariance, true_leds
from .test_statistics import CAMERA


def test_the_parent_jacobian_is_the_derivative_of_level_to_world():
    rng = np.random.default_rng(0)
    t = np.array([1.0, -2.0, 0.3])
    level = rng.normal(size=(5, 3))
    yaw = 0.4

    def world(q):
        return (level @ rot_z(q[0]).T + q[1:]).ravel()

    q = np.concatenate([[yaw], t])
    jac = parent_jacobian(world(q).reshape(-1, 3), t)
    numeric = np.column_stack([(world(q + h) - world(q - h)) / 2e-6 for h in 1e-6 * np.eye(4)])
    assert_allclose(jac, numeric, atol=1e-8)


def test_one_fix_is_shared_and_two_fixes_are_not():
    points = draw_points(CAMERA, true_leds(CAMERA, 3, seed=1), np.random.default_rng(0))
    cov = leds_covariance(points)
    own = stop_covariance()
    # A stop's block is its own covariance plus the parent's error through the lever arm;
    # the parent's error ties stops 0 and 1 together...
    leds = np.concatenate([p.point.leds_world for p in points])
    j = parent_jacobian(leds, np.zeros(3))
    assert_allclose(cov, np.kron(np.eye(3), own) + j @ PARENT_COV @ j.T, atol=1e-18)
    assert np.abs(cov[:12, 12:24]).max() > 0
    # ...but a stop measured from another fix (another station) shares nothing.
    other = ParentFix(1.0, 2, 0.0, np.zeros(3), PARENT_COV, 0.0)
    moved = [points[0], points[1], CheckPoint(points[2].point, points[2].sigma_px, other)]
    cov2 = leds_covariance(moved)
    assert_allclose(cov2[24:, :24], 0.0)
    assert_allclose(cov2[:24, :24], cov[:24, :24])


def test_a_childs_survey_error_ties_its_stops_and_not_the_other_childs():
    points = draw_points(CAMERA, true_leds(CAMERA, 3, seed=1), np.random.default_rng(0))
    plain = leds_covariance(points)
    marker = MarkerAssembly(survey_sigma=0.002)
    loads = [survey_loading(marker, rot_z(yaw)) for yaw in (0.0, 1.0, 2.0)]
    children = ("child1", "child2", "child1")
    surveyed = [
        CheckPoint(dataclasses.replace(p.point, child=c, survey_loading=load), p.sigma_px, p.parent)
        for p, c, load in zip(points, children, loads, strict=True)
    ]
    cov = leds_covariance(surveyed)
    added = cov - plain
    # Stops 0 and 2 (child1) share L0 L2^T; child2's stop shares nothing with them.
    assert_allclose(added[:12, :12], loads[0] @ loads[0].T, atol=1e-18)
    assert_allclose(added[:12, 24:], loads[0] @ loads[2].T, atol=1e-18)
    assert_allclose(added[12:24, 12:24], loads[1] @ loads[1].T, atol=1e-18)
    assert_allclose(added[:12, 12:24], 0.0, atol=1e-18)
    assert np.abs(added[:12, 24:]).max() > 1e-6  # millimetres squared: not negligible
    # A stop of fewer LEDs carries the rows of those it kept.
    cut = dataclasses.replace(surveyed[2].point, survey_loading=loads[2][:6])
    cut = dataclasses.replace(cut, leds_world=cut.leds_world[:2], pixels=cut.pixels[:2])
    cut = dataclasses.replace(cut, leds_covariance=cut.leds_covariance[:6, :6])
    fewer = leds_covariance(
        [*surveyed[:2], CheckPoint(cut, points[2].sigma_px[:2], points[2].parent)]
    )
    assert_allclose(fewer, cov[:30, :30], atol=1e-18)


def test_the_pixel_noise_has_a_floor():
    points = draw_points(CAMERA, true_leds(CAMERA, 1, seed=1), np.random.default_rng(0))
    tiny = [CheckPoint(points[0].point, np.array([0.001, np.nan, 0.2, 0.05]), points[0].parent)]
    assert_allclose(pixel_noise(tiny, 0.05), np.repeat([0.05, 0.05, 0.2, 0.05], 2) ** 2)
