"""Numerical Jacobians and parameter covariance of least-squares estimates.

The covariance of a least-squares estimate is ``sigma^2 (J^T J)^-1`` where J is the
Jacobian of the residuals at the solution and ``sigma^2 = |r|^2 / (M - P)`` the residual
variance (M residuals, P parameters). Covariances of derived quantities (Euler angles from a
rotation vector, the camera centre from a translation) follow by first-order propagation.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray


def central_jacobian(
    fun: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    x: NDArray[np.float64],
    steps: NDArray[np.float64],
    angle_mask: NDArray[np.bool_] | None = None,
) -> NDArray[np.float64]:
    """Central-difference Jacobian of ``fun`` at ``x``.

    Args:
        fun: maps (P,) parameters to (M,) outputs.
        x: (P,) point of evaluation.
        steps: (P,) absolute step per parameter.
        angle_mask: optional (M,) mask of outputs that are angles; their differences are
            wrapped to (-pi, pi] so a derivative taken across the +-pi seam stays right.

    Returns:
        (M, P) Jacobian.
    """
    x = np.asarray(x, dtype=float)
    cols = []
    for i, h in enumerate(steps):
        dx = np.zeros_like(x)
        dx[i] = h
        diff = fun(x + dx) - fun(x - dx)
        if angle_mask is not None:
            diff = np.where(angle_mask, np.angle(np.exp(1j * diff)), diff)
        cols.append(diff / (2.0 * h))
    return np.column_stack(cols)


def unit_covariance(jac: NDArray[np.float64]) -> NDArray[np.float64]:
    """(J^T J)^-1 for an (M, P) Jacobian, by SVD; all NaN if J is rank-deficient."""
    m, p = jac.shape
    _, s, vt = np.linalg.svd(jac, full_matrices=False)
    if s[-1] <= s[0] * max(m, p) * np.finfo(float).eps:
        # Some combination of parameters is not determined by the data at all.
        return np.full((p, p), np.nan)
    return (vt.T / s**2) @ vt


# Below this reciprocal condition of the column-scaled J^T J (1e-7 for 7 points of the
# paper's cameras) the rounding of J^T J (~1e-16 of its largest eigenvalue) reaches 1e-4
# of the smallest: the data do not determine some parameters, the covariance is NaN.
RCOND_MIN = 1e-12


def solve_or_nan(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Solve a stack of systems (..., P, P) x = (..., P, K); NaN where a matrix is singular."""
    try:
        return np.linalg.solve(a, b)
    except np.linalg.LinAlgError:
        out = np.full(np.broadcast_shapes(a.shape[:-2], b.shape[:-2]) + b.shape[-2:], np.nan)
        a_b, b_b = np.broadcast_to(a, out.shape[:-2] + a.shape[-2:]), np.broadcast_to(b, out.shape)
        for i in np.ndindex(out.shape[:-2]):
            with contextlib.suppress(np.linalg.LinAlgError):
                out[i] = np.linalg.solve(a_b[i], b_b[i])
        return out


def normal_inverse(normal: NDArray[np.float64]) -> NDArray[np.float64]:
    """(J^T J)^-1 of a stack (T, P, P) of normal matrices, inverted with its columns scaled
    to unit norm; NaN where the scaled matrix is singular: its reciprocal condition below
    ``RCOND_MIN``."""
    d = np.sqrt(np.diagonal(normal, axis1=1, axis2=2))
    d = np.where(d > 0.0, d, 1.0)
    dd = d[:, :, None] * d[:, None, :]
    scaled = normal / dd
    eig = np.linalg.eigvalsh(scaled)
    regular = eig[:, 0] > RCOND_MIN * eig[:, -1]
    inv = solve_or_nan(scaled, np.broadcast_to(np.eye(normal.shape[1]), normal.shape)) / dd
    return np.where(regular[:, None, None], inv, np.nan)


def least_squares_covariance(
    jac: NDArray[np.float64], residuals: NDArray[np.float64]
) -> tuple[NDArray[np.float64], float, int]:
    """Parameter covariance from the Jacobian and residuals at a least-squares solution.

    Args:
        jac: (M, P) Jacobian of the residuals.
        residuals: (M,) residuals at the solution.

    Returns:
        (P, P) covariance sigma^2 (J^T J)^-1, the residual variance sigma^2 = |r|^2 / dof,
        and the degrees of freedom dof = M - P. With no degrees of freedom sigma^2 is NaN
        (the covariance cannot be scaled); with a rank-deficient Jacobian the covariance is
        all NaN.
    """
    m, p = jac.shape
    dof = m - p
    sigma2 = float(residuals @ residuals / dof) if dof > 0 else float("nan")
    return sigma2 * unit_covariance(jac), sigma2, dof


def propagate_covariance(
    cov: NDArray[np.float64],
    transform: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    x: NDArray[np.float64],
    steps: NDArray[np.float64],
    angle_mask: NDArray[np.bool_] | None = None,
) -> NDArray[np.float64]:
    """First-order covariance of ``transform(x)`` given the covariance of x.

    Args:
        cov: (P, P) covariance of x.
        transform: maps (P,) -> (Q,).
        x: (P,) estimate. steps: (P,) finite-difference steps.
        angle_mask: (Q,) outputs that are angles (see :func:`central_jacobian`).

    Returns:
        (Q, Q) covariance.
    """
    g = central_jacobian(transform, x, steps, angle_mask)
    return g @ cov @ g.T


def own_position_variance(
    position_std: ArrayLike,
    sigma_px: ArrayLike,
    pixel_noise_px: float | None,
    points_variance: ArrayLike,
) -> NDArray[np.float64]:
    """The variance (trace, m^2) of a calibrated camera's centre from its own data: the
    pixel noise and the errors of its points.

    Tsai's standard deviations are the fit's residual sigma times its unit covariance. The
    residuals hold the points' errors too, which ``points_variance`` counts as they are
    (shared by the LEDs of a stop), so the pixel part takes the detector's noise
    ``pixel_noise_px`` in place of the residual sigma; without it (None) Tsai's
    standard deviations stand as they are, an upper bound of the pixel part.

    Args:
        position_std: (..., 3) Tsai's standard deviations of the centre, m.
        sigma_px: (...,) the fit's residual standard deviation, px.
        pixel_noise_px: the detector's pixel noise, px, or None.
        points_variance: (...,) the points' part, m^2
            (:func:`calib.point_errors.position_covariance_from_blocks`).
    """
    pixel = np.sum(np.asarray(position_std, dtype=float) ** 2, axis=-1)
    if pixel_noise_px is not None:
        with np.errstate(invalid="ignore", divide="ignore"):
            pixel = pixel * (pixel_noise_px / np.asarray(sigma_px, dtype=float)) ** 2
    return pixel + np.asarray(points_variance, dtype=float)
