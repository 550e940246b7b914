"""Tsai's first-order radial lens distortion, in pixel units.

Tsai's model goes from distorted to undistorted image coordinates:

    x_u = x_d * (1 + kappa1 * r_d**2),   r_d**2 = x_d**2 + y_d**2

(the inverse direction of OpenCV's model, which maps undistorted to distorted). Here the
coordinates are in pixels relative to the image centre, *before* the horizontal scale factor
sx is applied, so ``kappa1`` has units of 1/px^2.

Going from undistorted to distorted needs the root of a cubic. :func:`distort` solves it in
closed form (Cardano for kappa1 > 0, the trigonometric form for kappa1 < 0), not by
fixed-point iteration, so the projection is exact to floating-point precision.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

# Below this |kappa1 * r_u^2| the closed forms lose digits to cancellation; the series
# s = 1 - t + 3t^2 - 12t^3 + 55t^4 - 273t^5 is exact to double precision there.
_SERIES_LIMIT = 1e-3


def undistort(
    xy_d: NDArray[np.float64], kappa1: float | NDArray[np.float64]
) -> NDArray[np.float64]:
    """Distorted to undistorted image coordinates.

    Args:
        xy_d: (N, 2) distorted coordinates, px, relative to the image centre (before sx);
            or (..., N, 2) for several cameras at once.
        kappa1: Tsai's radial distortion coefficient, 1/px^2: a float, or an array that
            broadcasts against the leading shape of ``xy_d`` ((T, 1) for (T, N, 2)).

    Returns:
        undistorted coordinates, px, the shape of ``xy_d``.
    """
    r2 = np.sum(xy_d * xy_d, axis=-1)
    return xy_d * (1.0 + kappa1 * r2)[..., None]


def distortion_scale(t: NDArray[np.float64]) -> NDArray[np.float64]:
    """Solve ``t * s**3 + s - 1 = 0`` for the physical root s (r_d = s * r_u).

    ``t = kappa1 * r_u**2`` is dimensionless. For t >= 0 the cubic has one real root in
    (0, 1]. For -4/27 < t < 0 it has three; the physical one is the smallest positive root
    (the branch continuous with s = 1 at t = 0). For t <= -4/27 the undistorted radius lies
    beyond the fold of the distortion (no distorted point maps there) and NaN is returned.

    Args:
        t: array of kappa1 * r_u^2, any shape.

    Returns:
        s, same shape as t.
    """
    t = np.asarray(t, dtype=float)
    s = np.full(t.shape, np.nan)
    small = np.abs(t) < _SERIES_LIMIT
    ts = t[small]
    # Series reversion of s + t s^3 = 1 (coefficients: (-1)^n * binom(3n, n) / (2n + 1)).
    s[small] = 1.0 + ts * (
        -1.0 + ts * (3.0 + ts * (-12.0 + ts * (55.0 + ts * (-273.0 + ts * 1428.0))))
    )

    pos = (~small) & (t > 0)
    if pos.any():
        tp = t[pos]
        # Depressed cubic s^3 + p s + q = 0 with p = 1/t, q = -1/t; one real root.
        p = 1.0 / tp
        q = -1.0 / tp
        disc = np.sqrt(q * q / 4.0 + p**3 / 27.0)
        u = np.cbrt(-q / 2.0 + disc)  # the large cube root: no cancellation
        s[pos] = u - p / (3.0 * u)

    neg = (~small) & (t < 0) & (t > -4.0 / 27.0)
    if neg.any():
        tn = t[neg]
        p = 1.0 / tn  # negative
        q = -1.0 / tn  # positive
        m = 2.0 * np.sqrt(-p / 3.0)
        arg = np.clip(3.0 * q / (p * m), -1.0, 1.0)
        theta = np.arccos(arg) / 3.0
        roots = np.stack([m * np.cos(theta - 2.0 * np.pi * k / 3.0) for k in range(3)])
        roots = np.where(roots > 0, roots, np.inf)
        s[neg] = roots.min(axis=0)
    return s


def distort(xy_u: NDArray[np.float64], kappa1: float | NDArray[np.float64]) -> NDArray[np.float64]:
    """Undistorted to distorted image coordinates, the exact inverse of :func:`undistort`.

    Args:
        xy_u: (N, 2) undistorted coordinates, px, relative to the image centre (before sx);
            or (..., N, 2) for several cameras at once.
        kappa1: Tsai's radial distortion coefficient, 1/px^2: a float, or an array that
            broadcasts against the leading shape of ``xy_u`` ((T, 1) for (T, N, 2)).

    Returns:
        distorted coordinates, px, the shape of ``xy_u``. Rows beyond the fold of a
        negative kappa1 are NaN.
    """
    r2 = np.sum(xy_u * xy_u, axis=-1)
    s = distortion_scale(kappa1 * r2)
    return xy_u * s[..., None]


def max_undistorted_radius(kappa1: float) -> float:
    """Largest undistorted radius (px) that a distorted point maps to; inf for kappa1 >= 0."""
    if kappa1 >= 0:
        return float("inf")
    return float(np.sqrt(4.0 / (27.0 * -kappa1)))
