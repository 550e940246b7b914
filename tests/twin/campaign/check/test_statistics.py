"""The check's statistics against a known truth and noise: the chi-square of an unmoved
camera follows its distribution, a 2 cm shift or a 0.2 deg turn stands far above it, and
the re-pose's errors match its predicted covariance (MuJoCo's sysid tests' style: simulate
with a known truth, recover it)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2 as chi2_distribution

from calib.camera_covariance import perturbed_camera
from calib.pose_change import moved_camera, pose_change
from calib.synthetic import paper_camera
from twin.campaign.check import assess
from twin.campaign.check.consistency import chi_square_test
from twin.campaign.check.covariance import data_covariance, stacked

from .synthetic import draw_points, true_leds

CAMERA = paper_camera(1)
LEDS = true_leds(CAMERA, 5, seed=3)
CALIBRATION_STD = np.array([1.0, 0.8, 0.8, 2e-4, 5e-9, 1e-3, 1e-3, 5e-4, 5e-3, 3e-3, 3e-3])
"""A calibration's standard deviations (f, cx, cy px; sx; kappa1 1/px^2; turn rad; m)."""


def test_an_unmoved_camera_gives_chi_square_with_2n_degrees_of_freedom():
    rng = np.random.default_rng(10)
    draws = 300
    chi2 = []
    for _ in range(draws):
        points = draw_points(CAMERA, LEDS, rng, parent_translation=(2.0, 1.0, 0.0))
        leds, pixels = stacked(points)
        test = chi_square_test(CAMERA, leds, pixels, data_covariance(CAMERA, points), 0.05)
        chi2.append(test.chi2)
    dof = test.dof
    assert dof == 40
    # The mean of chi2 / dof has a standard deviation of sqrt(2 / dof / draws) = 0.013.
    assert np.mean(chi2) / dof == pytest.approx(1.0, abs=0.05)
    # At a 5 % false-alarm rate: 15 of 300 expected, binomial std 3.8.
    alarms = int(np.sum(np.array(chi2) > chi2_distribution.ppf(0.95, dof)))
    assert 4 <= alarms <= 28


@pytest.mark.parametrize(
    ("shift", "turn_deg"), [((0.02, 0.0, 0.0), (0.0, 0.0, 0.0)), ((0, 0, 0), (0.0, 0.2, 0.0))]
)
def test_a_2cm_shift_or_a_02deg_turn_is_found(shift, turn_deg):
    rng = np.random.default_rng(11)
    truth = moved_camera(CAMERA, shift, np.radians(turn_deg))
    for _ in range(5):
        check = assess("cam", CAMERA, draw_points(truth, LEDS, rng), 1e-3)
        assert check.moved
        # Far above the threshold: a 2 cm shift is about 5 px on this 770 px camera.
        assert check.consistency.chi2 > 5 * check.consistency.threshold


def test_the_repose_and_its_covariance_match_the_truth():
    rng = np.random.default_rng(12)
    cal_cov = np.diag(CALIBRATION_STD**2)
    move_shift, move_turn = np.array([0.01, 0.02, -0.01]), np.radians([0.1, -0.2, 0.05])
    change_z2, camera_z2 = [], []
    for _ in range(60):
        # The calibration is off by a draw from its covariance; the camera then moved.
        calibrated = perturbed_camera(CAMERA, CALIBRATION_STD * rng.standard_normal(11))
        truth = moved_camera(CAMERA, move_shift, move_turn)
        check = assess("cam", calibrated, draw_points(truth, LEDS, rng), 1e-3, cal_cov)
        new = check.repose
        assert new is not None
        # The change found (re-posed minus calibrated) against the move the camera made:
        # off by the check's noise and by the calibration's own error.
        e = np.concatenate([new.turn_rad - move_turn, new.shift_m - move_shift])
        change_z2.append(e @ np.linalg.solve(new.covariance, e))
        shift, turn = pose_change(truth, new.camera)
        intrinsics = [
            calibrated.f - CAMERA.f,
            calibrated.cx - CAMERA.cx,
            calibrated.cy - CAMERA.cy,
            calibrated.sx - CAMERA.sx,
            calibrated.kappa1 - CAMERA.kappa1,
        ]
        e = np.concatenate([intrinsics, turn, shift])
        camera_z2.append(e @ np.linalg.solve(new.camera_covariance, e))
    # Squared errors in units of their predicted covariance: the degrees of freedom on
    # average (6 for the change, 11 for the camera); 60 draws give about 5 % on the mean.
    assert np.mean(change_z2) == pytest.approx(6.0, rel=0.25)
    assert np.mean(camera_z2) == pytest.approx(11.0, rel=0.25)


def test_an_unmoved_camera_whose_calibration_is_off_passes_when_its_covariance_is_known():
    rng = np.random.default_rng(13)
    cal_cov = np.diag(CALIBRATION_STD**2)
    with_cov, without = [], []
    for _ in range(40):
        calibrated = perturbed_camera(CAMERA, CALIBRATION_STD * rng.standard_normal(11))
        points = draw_points(CAMERA, LEDS, rng)
        with_cov.append(assess("cam", calibrated, points, 1e-3, cal_cov).consistency.chi2)
        without.append(assess("cam", calibrated, points, 1e-3).consistency.chi2)
    assert np.mean(with_cov) / 40 == pytest.approx(1.0, abs=0.2)
    # Taken as exact, the calibration's own error reads as a move.
    assert np.mean(without) > 2 * np.mean(with_cov)
