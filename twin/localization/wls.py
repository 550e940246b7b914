"""Weighted least-squares CPS for two or more children (yaw + 3D translation).

Unknowns x = (yaw, tx, ty, tz) of the parent's levelled frame. For each child i the world
estimate w_i and the new measurement m_i (levelled frame) give the residual

    r_i(x) = w_i - Rz(yaw) m_i - t.

The residual's covariance is ``S = Cov(w) + blockdiag(Rz Cov(m_i) Rz^T)``: the joint
covariance of the children's world estimates (with the cross terms they inherit from the
parent's earlier pose) plus the new measurement noise. Gauss-Newton minimises
``r^T S^-1 r`` from a 2D Procrustes start; the result is the best linear unbiased estimate
to first order, with covariance ``(J^T S^-1 J)^-1``. For two noise-free children it equals
the paper's closed form.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.localization.checks import (
    DEFAULT_MAX_YAW_STD,
    DEFAULT_MIN_BASELINE,
    check_covariance,
    check_cps_input,
    check_measurement_covariances,
)
from twin.localization.planar import rot_z, rot_z_derivative, wrap_angle
from twin.localization.pose import CpsSolution, ParentPose, warn_if_poor


def procrustes_yaw(
    children_world: NDArray[np.float64], children_level: NDArray[np.float64]
) -> float:
    """Unweighted 2D Procrustes yaw, rad, from (N, 3) world and levelled positions."""
    w = children_world[:, :2] - children_world[:, :2].mean(axis=0)
    m = children_level[:, :2] - children_level[:, :2].mean(axis=0)
    cross = np.sum(m[:, 0] * w[:, 1] - m[:, 1] * w[:, 0])
    dot = np.sum(m[:, 0] * w[:, 0] + m[:, 1] * w[:, 1])
    return float(np.arctan2(cross, dot))


def _residual_system(
    yaw: float,
    t: NDArray[np.float64],
    world: NDArray[np.float64],
    level: NDArray[np.float64],
    cov_world: NDArray[np.float64],
    cov_level: NDArray[np.float64],
) -> tuple[NDArray, NDArray, NDArray, NDArray, NDArray]:
    """Residual (3N,), Jacobian (3N, 4), residual covariance S (3N, 3N), S^-1 J and
    blockdiag(Rz) (3N, 3N) at (yaw, t)."""
    n = world.shape[0]
    rot = rot_z(yaw)
    big_r = np.zeros((3 * n, 3 * n))
    for i in range(n):
        big_r[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] = rot
    s = cov_world + big_r @ cov_level @ big_r.T
    r = (world - level @ rot.T - t).reshape(-1)
    jac = np.empty((3 * n, 4))
    jac[:, 0] = -(level @ rot_z_derivative(yaw).T).reshape(-1)
    jac[:, 1:] = np.tile(-np.eye(3), (n, 1))
    try:
        np.linalg.cholesky(s)
    except np.linalg.LinAlgError:
        raise ValueError(
            "the residual covariance Cov(children_world) + Cov(measurements) is not positive "
            "definite; give each child a non-zero covariance"
        ) from None
    return r, jac, s, np.linalg.solve(s, jac), big_r


def solve_wls(
    children_world: ArrayLike,
    children_level: ArrayLike,
    cov_children_world: ArrayLike,
    cov_measurements: ArrayLike,
    *,
    timestamp: float = 0.0,
    max_iterations: int = 20,
    tolerance: float = 1e-13,
    min_baseline: float = DEFAULT_MIN_BASELINE,
    max_yaw_std: float = DEFAULT_MAX_YAW_STD,
) -> CpsSolution:
    """Solve the parent's pose from N >= 2 children by generalised least squares.

    Args:
        children_world: (N, 3) children's world positions, m.
        children_level: (N, 3) the children measured in the parent's levelled frame, m.
        cov_children_world: (3N, 3N) joint covariance of the world positions, m^2.
        cov_measurements: (N, 3, 3) covariance of each measurement, m^2.
        timestamp: time of the solution, s.
        max_iterations, tolerance: Gauss-Newton stop (step norm in rad and m).
        min_baseline: smallest accepted horizontal baseline, m.
        max_yaw_std: predicted yaw std, rad, above which :class:`PoorGeometryWarning` is
            raised.

    Returns:
        The solution, with covariance, Jacobians and the chi-square of the residuals
        (expected value 3N - 4 when the covariances are right; a large value means a wrong
        prism, a child that moved, or a bad covariance).

    Raises:
        ValueError: fewer than two children, NaN, horizontal coincidence, or a residual
            covariance that is not positive definite.
    """
    w, m, baseline = check_cps_input(children_world, children_level, min_baseline)
    n = w.shape[0]
    cw = check_covariance(cov_children_world, 3 * n, "cov_children_world")
    cm = check_measurement_covariances(cov_measurements, n)

    yaw = procrustes_yaw(w, m)
    t = np.mean(w - m @ rot_z(yaw).T, axis=0)
    iterations = 0
    for iterations in range(1, max_iterations + 1):  # noqa: B007
        r, jac, _, wj, _ = _residual_system(yaw, t, w, m, cw, cm)
        step = -np.linalg.solve(jac.T @ wj, wj.T @ r)
        yaw = float(wrap_angle(yaw + step[0]))
        t = t + step[1:]
        if np.linalg.norm(step) < tolerance:
            break

    r, jac, s, wj, big_r = _residual_system(yaw, t, w, m, cw, cm)
    gain = np.linalg.solve(jac.T @ wj, wj.T)  # (4, 3N) = (J^T S^-1 J)^-1 J^T S^-1
    g_world = -gain
    g_level = gain @ big_r
    cov = g_world @ cw @ g_world.T + g_level @ cm @ g_level.T
    solution = CpsSolution(
        pose=ParentPose(yaw, t, 0.5 * (cov + cov.T), timestamp),
        method="wls",
        children_jacobian=g_world,
        measurement_jacobian=g_level,
        baseline=baseline,
        chi2=float(r @ np.linalg.solve(s, r)),
        dof=3 * n - 4,
        iterations=iterations,
    )
    warn_if_poor(solution, max_yaw_std)
    return solution
