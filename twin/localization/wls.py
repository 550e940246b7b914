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

Consistency: the minimum ``chi2 = r^T S^-1 r`` follows a chi-square law with ``3N - 4``
degrees of freedom for consistent data. Above its quantile at ``false_alarm_rate``
(:mod:`twin.instruments.consistency`) :class:`InconsistentChildrenError` is raised: a child
moved between the two measurements, or a wrong prism was locked. Gauss-Newton that stops
at ``max_iterations`` before its step tolerance raises :class:`ConvergenceWarning` and
marks the solution ``converged=False``.
"""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.rotation import rot_z, rot_z_derivative, wrap_angle
from twin.instruments.consistency import (
    DEFAULT_FALSE_ALARM_RATE,
    check_false_alarm_rate,
    raise_if_inconsistent,
)
from twin.instruments.errors import InconsistentChildrenError
from twin.localization.input_checks import (
    DEFAULT_MAX_YAW_STD,
    DEFAULT_MIN_BASELINE,
    ConvergenceWarning,
    check_covariance,
    check_cps_input,
    check_measurement_covariances,
)
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
    false_alarm_rate: float | None = DEFAULT_FALSE_ALARM_RATE,
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
        false_alarm_rate: probability that consistent data raise
            :class:`InconsistentChildrenError`; None switches the test off.

    Returns:
        The solution, with covariance, Jacobians and the chi-square of the residuals
        (expected value 3N - 4 when the covariances are right).

    Raises:
        InconsistentChildrenError: chi2 above its quantile (a wrong prism, a child that
            moved, or a bad covariance); ``details`` hold ``chi2``, ``dof``, ``threshold``
            and the rejected ``solution``.
        ValueError: fewer than two children, NaN, horizontal coincidence, a covariance
            that is not symmetric positive semidefinite, or a residual covariance that is
            not positive definite.

    Warns:
        ConvergenceWarning: Gauss-Newton reached ``max_iterations`` before ``tolerance``.
    """
    rate = check_false_alarm_rate(false_alarm_rate)
    if max_iterations < 1:
        raise ValueError(f"max_iterations must be at least 1, got {max_iterations}")
    w, m, baseline = check_cps_input(children_world, children_level, min_baseline)
    n = w.shape[0]
    cw = check_covariance(cov_children_world, 3 * n, "cov_children_world")
    cm = check_measurement_covariances(cov_measurements, n)

    yaw = procrustes_yaw(w, m)
    t = np.mean(w - m @ rot_z(yaw).T, axis=0)
    iterations, converged, step_norm = 0, False, np.inf
    for iterations in range(1, max_iterations + 1):  # noqa: B007
        r, jac, _, wj, _ = _residual_system(yaw, t, w, m, cw, cm)
        step = -np.linalg.solve(jac.T @ wj, wj.T @ r)
        yaw = float(wrap_angle(yaw + step[0]))
        t = t + step[1:]
        step_norm = float(np.linalg.norm(step))
        if step_norm < tolerance:
            converged = True
            break
    if not converged:
        warnings.warn(
            f"WLS did not converge in {max_iterations} Gauss-Newton iterations: last step "
            f"{step_norm:.3g} (rad and m) above the tolerance {tolerance:g}",
            ConvergenceWarning,
            stacklevel=2,
        )

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
        converged=converged,
    )
    assert solution.chi2 is not None
    raise_if_inconsistent(
        solution.chi2,
        solution.dof,
        rate,
        InconsistentChildrenError,
        f"the {n} children do not fit their world positions (a child moved or a wrong prism)",
        solution=solution,
    )
    warn_if_poor(solution, max_yaw_std)
    return solution
