"""Check data drawn from a known truth and a known noise model, for the check's tests."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from calib.camera import TsaiCamera
from calib.synthetic import led_points
from twin.campaign.check.covariance import parent_jacobian
from twin.campaign.check.gathering import CheckPoint
from twin.campaign.records import DataPoint, ParentFix

SIGMA_PX = 0.05
COMMON_M = 1e-3  # each stop's LEDs share this error (the marker's pose), m per axis
OWN_M = 0.5e-3  # and each LED has this much of its own, m per axis
PARENT_COV = np.diag([2e-5**2, 0.5e-3**2, 0.5e-3**2, 0.3e-3**2])  # yaw, x, y, z


def stop_covariance(n: int = 4) -> NDArray[np.float64]:
    """(3n, 3n) covariance of one stop's LEDs in W without the parent's part."""
    return COMMON_M**2 * np.kron(np.ones((n, n)), np.eye(3)) + OWN_M**2 * np.eye(3 * n)


def true_leds(camera: TsaiCamera, stops: int, seed: int) -> NDArray[np.float64]:
    """(stops, 4, 3) LED positions in the camera's view, m."""
    rng = np.random.default_rng(seed)
    return led_points(camera, 4 * stops, rng, margin_px=20.0)[: 4 * stops].reshape(stops, 4, 3)


def draw_points(
    seen_by: TsaiCamera,
    leds: NDArray[np.float64],
    rng: np.random.Generator,
    parent_translation=(0.0, 0.0, 0.0),
) -> list[CheckPoint]:
    """The check data of LEDs ``leds`` (stops, 4, 3) seen by camera ``seen_by``: measured
    3D positions and pixels with errors drawn from the noise model."""
    t = np.asarray(parent_translation, dtype=float)
    fix = ParentFix(0.0, 1, 0.0, t, PARENT_COV, 0.0)
    all_leds = leds.reshape(-1, 3)
    parent_error = parent_jacobian(all_leds, t) @ rng.multivariate_normal(np.zeros(4), PARENT_COV)
    parent_error = parent_error.reshape(leds.shape)
    cov = stop_covariance(leds.shape[1])
    chol = np.linalg.cholesky(cov)
    out = []
    for k, stop in enumerate(leds):
        measured = stop + (chol @ rng.standard_normal(cov.shape[0])).reshape(-1, 3)
        measured = measured + parent_error[k]
        pixels = seen_by.project(stop) + SIGMA_PX * rng.standard_normal((len(stop), 2))
        point = DataPoint(
            float(k), "reference", "cam", 0, "child1", measured, pixels, stop[0, :2], cov
        )
        out.append(CheckPoint(point, np.full(len(stop), SIGMA_PX), fix))
    return out
