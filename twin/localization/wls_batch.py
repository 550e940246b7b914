"""Weighted least-squares CPS in T trials at once: :func:`.wls.solve_wls` over arrays.

The same Gauss-Newton as the scalar solver, from the same 2D Procrustes start, with the
same stop: each trial iterates until its own step norm falls below ``tolerance`` and is
then left alone while the others go on, so every trial takes the iterations the scalar
solver takes on its data. The solution, its covariance ``(J^T S^-1 J)^-1``-sandwich, the
Jacobians and the chi-square (``3N - 4`` degrees of freedom) follow per trial. What the
scalar solver raises or warns for one trial's data is a flag of
:class:`twin.localization.pose_batch.CpsSolutionBatch` (see :mod:`.input_checks_batch`).
"""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.rotation import rot_z, rot_z_derivative, wrap_angle
from twin.instruments.consistency import (
    DEFAULT_FALSE_ALARM_RATE,
    check_false_alarm_rate,
    exceeds_threshold,
)
from twin.localization.input_checks import (
    DEFAULT_MAX_YAW_STD,
    DEFAULT_MIN_BASELINE,
    ConvergenceWarning,
)
from twin.localization.input_checks_batch import (
    check_cps_input_batch,
    poor_geometry,
    substitute_trials,
)
from twin.localization.pose_batch import CpsSolutionBatch, ParentPoseBatch


def procrustes_yaw_batch(
    children_world: NDArray[np.float64], children_level: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(T,) unweighted 2D Procrustes yaws, rad, from (T, N, 3) world and levelled points."""
    w = children_world[..., :2] - children_world[..., :2].mean(axis=-2, keepdims=True)
    m = children_level[..., :2] - children_level[..., :2].mean(axis=-2, keepdims=True)
    cross = np.sum(m[..., 0] * w[..., 1] - m[..., 1] * w[..., 0], axis=-1)
    dot = np.sum(m[..., 0] * w[..., 0] + m[..., 1] * w[..., 1], axis=-1)
    return np.arctan2(cross, dot)


def _transpose(a: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.swapaxes(a, -1, -2)


def _residual_system(
    yaw: NDArray[np.float64],
    t: NDArray[np.float64],
    world: NDArray[np.float64],
    level: NDArray[np.float64],
    cov_world: NDArray[np.float64],
    cov_level: NDArray[np.float64],
    check: bool = False,
) -> tuple[NDArray, NDArray, NDArray, NDArray, NDArray]:
    """Residual (T, 3N), Jacobian (T, 3N, 4), residual covariance S (T, 3N, 3N), S^-1 J
    and blockdiag(Rz) (T, 3N, 3N) at (yaw (T,), t (T, 3)); ``check``: raise ValueError
    unless every S is positive definite."""
    n_trials, n = world.shape[:2]
    rot = rot_z(yaw)
    big_r = np.zeros((n_trials, 3 * n, 3 * n))
    for i in range(n):
        big_r[:, 3 * i : 3 * i + 3, 3 * i : 3 * i + 3] = rot
    s = cov_world + big_r @ cov_level @ _transpose(big_r)
    r = (world - level @ _transpose(rot) - t[:, None, :]).reshape(n_trials, 3 * n)
    jac = np.empty((n_trials, 3 * n, 4))
    jac[:, :, 0] = -(level @ _transpose(rot_z_derivative(yaw))).reshape(n_trials, 3 * n)
    jac[:, :, 1:] = np.tile(-np.eye(3), (n, 1))
    if check:
        _check_positive_definite(s)
    return r, jac, s, np.linalg.solve(s, jac), big_r


def _check_positive_definite(s: NDArray[np.float64]) -> None:
    # Cholesky of a stack raises for the first matrix that is not positive definite.
    try:
        np.linalg.cholesky(s)
    except np.linalg.LinAlgError:
        raise ValueError(
            "the residual covariance Cov(children_world) + Cov(measurements) is not positive "
            "definite; give each child a non-zero covariance"
        ) from None


def solve_wls_batch(
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
) -> CpsSolutionBatch:
    """Solve the parent's pose from N >= 2 children in each of T trials.

    Args:
        children_world: (T, N, 3) children's world positions, m.
        children_level: (T, N, 3) the children measured in the parent's levelled frame, m.
        cov_children_world: (T, 3N, 3N) joint covariance of the world positions, m^2.
        cov_measurements: (T, N, 3, 3) covariance of each measurement, m^2.
        timestamp: time of the solutions, s.
        max_iterations, tolerance: Gauss-Newton stop of each trial (step norm, rad and m).
        min_baseline: smallest accepted horizontal baseline, m.
        max_yaw_std: predicted yaw std, rad, above which ``poor_yaw`` is set.
        false_alarm_rate: probability that consistent data set ``inconsistent``; None
            switches the test off.

    Returns:
        Per trial what :func:`twin.localization.wls.solve_wls` returns, with flags where it
        raises or warns.

    Raises:
        ValueError: wrong shapes, a covariance that is not symmetric positive
            semidefinite, or a residual covariance that is not positive definite.

    Warns:
        ConvergenceWarning: some trials reached ``max_iterations`` before ``tolerance``
            (once, with their number).
    """
    rate = check_false_alarm_rate(false_alarm_rate)
    if max_iterations < 1:
        raise ValueError(f"max_iterations must be at least 1, got {max_iterations}")
    w, m, cw, cm = check_cps_input_batch(
        children_world, children_level, cov_children_world, cov_measurements
    )
    n_trials, n = w.shape[:2]
    baseline, bad = poor_geometry(w, m, min_baseline)
    w, m, cw, cm = substitute_trials(bad, w, m, cw, cm)

    yaw = procrustes_yaw_batch(w, m)
    t = np.mean(w - m @ _transpose(rot_z(yaw)), axis=-2)
    iterations = np.zeros(n_trials, dtype=np.int64)
    converged = np.zeros(n_trials, dtype=bool)
    active = np.arange(n_trials)
    for iteration in range(1, max_iterations + 1):
        a = active
        r, jac, _, wj, _ = _residual_system(
            yaw[a], t[a], w[a], m[a], cw[a], cm[a], check=iteration == 1
        )
        step = -np.linalg.solve(_transpose(jac) @ wj, _transpose(wj) @ r[..., None])[..., 0]
        yaw[a] = wrap_angle(yaw[a] + step[:, 0])
        t[a] = t[a] + step[:, 1:]
        iterations[a] = iteration
        done = np.linalg.norm(step, axis=-1) < tolerance
        converged[a[done]] = True
        active = a[~done]
        if active.size == 0:
            break
    if not converged.all():
        warnings.warn(
            f"WLS did not converge in {max_iterations} Gauss-Newton iterations in "
            f"{int(np.count_nonzero(~converged))} of {n_trials} trials",
            ConvergenceWarning,
            stacklevel=2,
        )

    r, jac, s, wj, big_r = _residual_system(yaw, t, w, m, cw, cm)
    # (T, 4, 3N) gain (J^T S^-1 J)^-1 J^T S^-1
    gain = np.linalg.solve(_transpose(jac) @ wj, _transpose(wj))
    g_world = -gain
    g_level = gain @ big_r
    cov = g_world @ cw @ _transpose(g_world) + g_level @ cm @ _transpose(g_level)
    cov = 0.5 * (cov + _transpose(cov))
    chi2 = np.sum(r * np.linalg.solve(s, r[..., None])[..., 0], axis=-1)
    for arr in (yaw, t, cov, g_world, g_level, chi2):
        arr[bad] = np.nan
    pose = ParentPoseBatch(yaw, t, cov, timestamp)
    dof = 3 * n - 4
    return CpsSolutionBatch(
        pose=pose,
        method="wls",
        children_jacobian=g_world,
        measurement_jacobian=g_level,
        baseline=baseline,
        chi2=chi2,
        dof=dof,
        iterations=iterations,
        converged=converged,
        inconsistent=exceeds_threshold(chi2, dof, rate) & ~bad,
        poor_geometry=bad,
        poor_yaw=pose.yaw_std > max_yaw_std,
    )
