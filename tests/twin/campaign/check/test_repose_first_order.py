"""The re-pose's covariances as the first-order maps they stand for, measured by finite
differences of the re-pose itself: the change's and the re-posed camera's response to the
calibration's error (under a correlated calibration covariance, whose cross terms between
the intrinsics and the pose a diagonal one leaves out) and the pose's response to the
pixels (under a correlated data covariance)."""

from __future__ import annotations

import numpy as np
from numpy.testing import assert_allclose

from calib.camera_covariance import perturbed_camera
from calib.pose_change import pose_change
from calib.synthetic import paper_camera
from twin.campaign.check.repose import repose

from .synthetic import true_leds

CAMERA = paper_camera(1)
LEDS = true_leds(CAMERA, 3, seed=5).reshape(-1, 3)  # 12 points
PIXELS = CAMERA.project(LEDS)
STD = np.array([1.0, 0.8, 0.8, 2e-4, 5e-9, 1e-3, 1e-3, 5e-4, 5e-3, 3e-3, 3e-3])
"""A calibration's standard deviations (f, cx, cy px; sx; kappa1 1/px^2; turn rad; m)."""


def _correlated(rng: np.random.Generator, std: np.ndarray) -> np.ndarray:
    """A covariance with standard deviations ``std`` and strong correlations."""
    a = rng.normal(size=(len(std), len(std)))
    r = a @ a.T + 0.1 * np.eye(len(std))
    d = np.sqrt(np.diag(r))
    return np.outer(std, std) * r / np.outer(d, d)


def _errors(calibrated, pixels) -> tuple[np.ndarray, np.ndarray]:
    """The change found (turn, shift) and the re-posed camera's error against the truth
    (intrinsics, turn, shift), re-posing ``calibrated`` on ``pixels``."""
    found = repose(calibrated, LEDS, pixels, np.zeros((2 * len(LEDS),) * 2))
    shift, turn = pose_change(CAMERA, found.camera)
    intrinsics = [
        calibrated.f - CAMERA.f,
        calibrated.cx - CAMERA.cx,
        calibrated.cy - CAMERA.cy,
        calibrated.sx - CAMERA.sx,
        calibrated.kappa1 - CAMERA.kappa1,
    ]
    return np.concatenate([found.turn_rad, found.shift_m]), np.concatenate(
        [intrinsics, turn, shift]
    )


def _same_covariance(got: np.ndarray, want: np.ndarray) -> None:
    std = np.sqrt(np.diag(want))
    assert_allclose(np.sqrt(np.diag(got)), std, rtol=2e-3)
    assert_allclose(got / np.outer(std, std), want / np.outer(std, std), atol=2e-3)


def test_the_calibrations_correlated_error_maps_to_the_change_and_the_camera():
    # The camera did not move and its pixels are exact: a calibration off by d gives the
    # change -M d and the re-posed camera the error K d_i. Their covariances must be
    # M C M^T and K C_ii K^T with M and K measured here, d by d.
    cov = _correlated(np.random.default_rng(14), STD)
    change_map, camera_map = np.zeros((6, 11)), np.zeros((11, 11))
    for j in range(11):
        h = np.zeros(11)
        h[j] = 0.01 * STD[j]
        plus = _errors(perturbed_camera(CAMERA, h), PIXELS)
        minus = _errors(perturbed_camera(CAMERA, -h), PIXELS)
        change_map[:, j] = (plus[0] - minus[0]) / (2 * h[j])
        camera_map[:, j] = (plus[1] - minus[1]) / (2 * h[j])
    # The re-pose keeps the intrinsics and fits the pose anew: the camera's error does
    # not depend on the calibrated pose.
    assert np.abs(camera_map[:, 5:] * STD[5:]).max() < 1e-6 * np.abs(camera_map * STD).max()
    found = repose(CAMERA, LEDS, PIXELS, np.zeros((2 * len(LEDS),) * 2), cov)
    _same_covariance(found.covariance, change_map @ cov @ change_map.T)
    _same_covariance(found.camera_covariance, camera_map @ cov @ camera_map.T)
    # A diagonal covariance of the same standard deviations gives another change
    # covariance: the cross terms count.
    diagonal = repose(CAMERA, LEDS, PIXELS, np.zeros((24, 24)), np.diag(STD**2))
    assert (
        np.abs(diagonal.covariance - found.covariance).max() > 0.1 * np.abs(found.covariance).max()
    )


def test_the_pixels_correlated_errors_map_to_the_pose():
    # The pose found moves by A e for pixel errors e: the change's and the camera's pose
    # covariances from the data are A S A^T. With S = V V^T (correlated pixels), that is
    # (A V)(A V)^T, A V measured here column by column of V.
    rng = np.random.default_rng(15)
    n = 2 * len(LEDS)
    v = 0.05 * rng.normal(size=(n, 8)) / np.sqrt(8)
    moved = np.zeros((6, v.shape[1]))
    for j, column in enumerate(v.T):
        step = 0.02 * column.reshape(-1, 2)
        plus = _errors(CAMERA, PIXELS + step)
        minus = _errors(CAMERA, PIXELS - step)
        moved[:, j] = (plus[0] - minus[0]) / 0.04
    found = repose(CAMERA, LEDS, PIXELS, v @ v.T)
    want = moved @ moved.T
    _same_covariance(found.covariance, want)
    assert_allclose(found.camera_covariance[:5], 0.0)
    _same_covariance(found.camera_covariance[5:, 5:], want)
