"""The joint uncertainty of a camera's check data: the LEDs' 3D positions and their pixels.

The LEDs of one stop share the child's measured marker pose (their covariance is the data
point's, :attr:`twin.campaign.records.DataPoint.leds_covariance`), and every LED measured
from one station shares the parent's pose error (yaw and translation, from CPS; zero at
the first station, which defines W). The pixels carry the detector's own noise.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from calib.camera import TsaiCamera
from calib.tsai import pixel_jacobian
from twin.campaign.check.gathering import CheckPoint
from twin.campaign.records import ParentFix

MIN_PIXEL_SIGMA = 0.05
"""Least standard deviation of an LED's pixel coordinate the check assumes, px (``twin
check --min-pixel-sigma``). A detector's own prediction counts only the image noise (a few
thousandths of a pixel on the twin's rendered images), while its centroids are off by
about 0.05 px RMS there (the render fidelity's measured detection error, which the
geometric fidelity simulates): the pixel grid and the LED's shape add what the image noise
does not show. A camera whose centroids are worse (interlaced, compressed) needs more."""


def stacked(points: Sequence[CheckPoint]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(N, 3) LED positions in W, m, and (N, 2) their pixels, px, of all the points."""
    leds = [np.asarray(p.point.leds_world, dtype=float).reshape(-1, 3) for p in points]
    pixels = [np.asarray(p.point.pixels, dtype=float).reshape(-1, 2) for p in points]
    return np.concatenate(leds or [np.zeros((0, 3))]), np.concatenate(pixels or [np.zeros((0, 2))])


def leds_covariance(points: Sequence[CheckPoint]) -> NDArray[np.float64]:
    """(3N, 3N) joint covariance of the LED positions in W, m^2: each stop's own block,
    plus the parent's pose error, shared by every LED measured from the same fix, plus the
    marker assembly's surveying error, shared by every stop of the same child
    (:attr:`twin.campaign.records.DataPoint.survey_loading`).

    A point whose covariance is unknown (empty) contributes only the parent's part.
    """
    leds, _ = stacked(points)
    n = len(leds)
    cov = np.zeros((3 * n, 3 * n))
    # The rows of the LEDs measured from each fix of the parent (the same record).
    fixes: dict[int, tuple[ParentFix, list[int]]] = {}
    # Each child's rows and their loadings on its surveying error.
    surveyed: dict[str, tuple[list[NDArray[np.intp]], list[NDArray[np.float64]]]] = {}
    rows = 0
    for p in points:
        k = len(np.asarray(p.point.leds_world).reshape(-1, 3))
        own = np.asarray(p.point.leds_covariance, dtype=float)
        if own.size:
            cov[3 * rows : 3 * (rows + k), 3 * rows : 3 * (rows + k)] += own
        fixes.setdefault(id(p.parent), (p.parent, []))[1].extend(range(rows, rows + k))
        loading = np.asarray(p.point.survey_loading, dtype=float)
        if loading.size:
            mine = surveyed.setdefault(p.point.child, ([], []))
            mine[0].append(np.arange(3 * rows, 3 * (rows + k)))
            mine[1].append(loading.reshape(3 * k, -1))
        rows += k
    for child_rows, loadings in surveyed.values():
        idx, load = np.concatenate(child_rows), np.concatenate(loadings)
        cov[np.ix_(idx, idx)] += load @ load.T
    for fix, mine in fixes.values():
        idx = np.array(mine)
        cols = (3 * idx[:, None] + np.arange(3)).ravel()
        j = parent_jacobian(leds[idx], np.asarray(fix.translation, dtype=float))
        cov[np.ix_(cols, cols)] += j @ np.asarray(fix.covariance, dtype=float) @ j.T
    return cov


def parent_jacobian(
    leds_world: NDArray[np.float64], parent_translation: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(3N, 4) derivative of (N, 3) points in W, measured from the parent, with respect
    to the parent's (yaw, x, y, z): W = Rz(yaw) L + t, so a turn about the parent's
    vertical axis moves a point by (-dy, dx, 0) per radian, a shift of t by as much."""
    arm = np.asarray(leds_world, dtype=float) - parent_translation
    j = np.zeros((len(arm), 3, 4))
    j[:, 0, 0], j[:, 1, 0] = -arm[:, 1], arm[:, 0]
    j[:, :, 1:] = np.eye(3)
    return j.reshape(-1, 4)


def pixel_noise(
    points: Sequence[CheckPoint], min_sigma_px: float = MIN_PIXEL_SIGMA
) -> NDArray[np.float64]:
    """(2N,) variance of each pixel coordinate (u0, v0, u1, ...), px^2: the detector's
    standard deviation, at least ``min_sigma_px``, squared."""
    sigma = np.concatenate([np.asarray(p.sigma_px, dtype=float) for p in points] or [[]])
    sigma = np.where(np.isfinite(sigma), np.maximum(sigma, min_sigma_px), min_sigma_px)
    return np.repeat(sigma**2, 2)


def data_covariance(
    camera: TsaiCamera, points: Sequence[CheckPoint], min_sigma_px: float = MIN_PIXEL_SIGMA
) -> NDArray[np.float64]:
    """(2N, 2N) covariance of the points' residuals pixel - projection through ``camera``,
    px^2, from the data alone (:func:`residual_covariance` of the points' own noise, the
    pixels' standard deviation at least ``min_sigma_px``)."""
    leds, _ = stacked(points)
    # A point moving is the camera moving the other way.
    jac = -pixel_jacobian(camera, leds)[:, :, 8:11]
    return residual_covariance(jac, leds_covariance(points), pixel_noise(points, min_sigma_px))


def residual_covariance(
    jacobian_px_per_m: NDArray[np.float64],
    leds_cov: NDArray[np.float64],
    pixel_var: NDArray[np.float64],
) -> NDArray[np.float64]:
    """(2N, 2N) covariance of the residuals pixel - projection of the measured LEDs, px^2:
    the detector's noise plus the LEDs' 3D covariance seen through the camera.

    Args:
        jacobian_px_per_m: (N, 2, 3) derivative of each LED's pixel with respect to its
            position in W, px/m.
        leds_cov: (3N, 3N) the LEDs' joint covariance, m^2.
        pixel_var: (2N,) variance of each pixel coordinate, px^2.
    """
    j = np.asarray(jacobian_px_per_m, dtype=float)
    n = len(j)
    big = np.zeros((2 * n, 3 * n))
    for i in range(n):
        big[2 * i : 2 * i + 2, 3 * i : 3 * i + 3] = j[i]
    return big @ leds_cov @ big.T + np.diag(pixel_var)
