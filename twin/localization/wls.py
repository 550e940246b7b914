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

:func:`solve_wls_batch` solves T trials at once: each trial iterates until its own step
norm falls below ``tolerance`` and is then left alone while the others go on, so a trial's
result does not depend on the others. What is wrong with one trial's data is a flag of
:class:`CpsSolutionBatch`; :func:`solve_wls` is the one-trial form, which raises and warns
where the batch flags.
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
    raise_if_inconsistent,
)
from twin.instruments.errors import InconsistentChildrenError
from twin.localization.input_checks import (
    DEFAULT_MAX_YAW_STD,
    DEFAULT_MIN_BASELINE,
    ConvergenceWarning,
    check_covariance,
    check_cps_input_batch,
    check_cps_pair,
    check_measurement_covariances,
    coincide_message,
    poor_geometry,
    substitute_trials,
)
from twin.localization.pose import CpsSolution, CpsSolutionBatch, ParentPoseBatch, warn_if_poor


def procrustes_yaw_batch(
    children_world: NDArray[np.float64], children_level: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(T,) unweighted 2D Procrustes yaws, rad, from (T, N, 3) world and levelled points."""
    w = children_world[..., :2] - children_world[..., :2].mean(axis=-2, keepdims=True)
    m = children_level[..., :2] - children_level[..., :2].mean(axis=-2, keepdims=True)
    cross = np.sum(m[..., 0] * w[..., 1] - m[..., 1] * w[..., 0], axis=-1)
    dot = np.sum(m[..., 0] * w[..., 0] + m[..., 1] * w[..., 1], axis=-1)
    return np.arctan2(cross, dot)


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
    s = cov_world + big_r @ cov_level @ big_r.mT
    r = (world - level @ rot.mT - t[:, None, :]).reshape(n_trials, 3 * n)
    jac = np.empty((n_trials, 3 * n, 4))
    jac[:, :, 0] = -(level @ rot_z_derivative(yaw).mT).reshape(n_trials, 3 * n)
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


def _solve(
    w: NDArray[np.float64],
    m: NDArray[np.float64],
    cw: NDArray[np.float64],
    cm: NDArray[np.float64],
    timestamp: float,
    max_iterations: int,
    tolerance: float,
    min_baseline: float,
    max_yaw_std: float,
    rate: float | None,
) -> tuple[CpsSolutionBatch, NDArray[np.float64]]:
    """Gauss-Newton of checked (T, N, 3) points and (T, 3N, 3N) covariances; returns the
    solutions and the last step norm (rad and m) of the trials that did not converge."""
    n_trials, n = w.shape[:2]
    baseline, bad = poor_geometry(w, m, min_baseline)
    w, m, cw, cm = substitute_trials(bad, w, m, cw, cm)

    yaw = procrustes_yaw_batch(w, m)
    t = np.mean(w - m @ rot_z(yaw).mT, axis=-2)
    iterations = np.full(n_trials, max_iterations, dtype=np.int64)
    converged = np.zeros(n_trials, dtype=bool)
    step_norm = np.zeros(n_trials)
    active = np.arange(n_trials)
    for iteration in range(1, max_iterations + 1):
        # Slices, not copies, while every trial iterates.
        a = slice(None) if active.size == n_trials else active
        r, jac, _, wj, _ = _residual_system(
            yaw[a], t[a], w[a], m[a], cw[a], cm[a], check=iteration == 1
        )
        step = -np.linalg.solve(jac.mT @ wj, wj.mT @ r[..., None])[..., 0]
        yaw[a] = wrap_angle(yaw[a] + step[:, 0])
        t[a] += step[:, 1:]
        # sqrt of a (1, 4) @ (4, 1) product: np.linalg.norm of one step, to the last bit.
        norm = np.sqrt(step[:, None, :] @ step[:, :, None])[:, 0, 0]
        done = norm < tolerance
        if done.any():
            finished = active[done]
            iterations[finished] = iteration
            converged[finished] = True
            active, norm = active[~done], norm[~done]
            if active.size == 0:
                break
    step_norm[active] = norm

    r, jac, s, wj, big_r = _residual_system(yaw, t, w, m, cw, cm)
    # (T, 4, 3N) gain (J^T S^-1 J)^-1 J^T S^-1
    gain = np.linalg.solve(jac.mT @ wj, wj.mT)
    g_world = -gain
    g_level = gain @ big_r
    cov = g_world @ cw @ g_world.mT + g_level @ cm @ g_level.mT
    cov = 0.5 * (cov + cov.mT)
    # A (1, 3N) @ (3N, 1) product per trial: the dot product of one residual.
    chi2 = (r[:, None, :] @ np.linalg.solve(s, r[..., None]))[:, 0, 0]
    if bad.any():
        for arr in (yaw, t, cov, g_world, g_level, chi2):
            arr[bad] = np.nan
    pose = ParentPoseBatch(yaw, t, cov, timestamp)
    dof = 3 * n - 4
    solution = CpsSolutionBatch(
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
    return solution, step_norm


def _check_iterations(max_iterations: int) -> None:
    if max_iterations < 1:
        raise ValueError(f"max_iterations must be at least 1, got {max_iterations}")


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
        The solutions with covariance, Jacobians and the chi-square of the residuals
        (expected value 3N - 4 when the covariances are right), and the flags
        ``inconsistent``, ``poor_geometry`` (no solution: NaN) and ``poor_yaw``.

    Raises:
        ValueError: wrong shapes, a covariance that is not symmetric positive
            semidefinite, or a residual covariance that is not positive definite.

    Warns:
        ConvergenceWarning: some trials reached ``max_iterations`` before ``tolerance``
            (once, with their number).
    """
    rate = check_false_alarm_rate(false_alarm_rate)
    _check_iterations(max_iterations)
    w, m, cw, cm = check_cps_input_batch(
        children_world, children_level, cov_children_world, cov_measurements
    )
    solution, _ = _solve(
        w, m, cw, cm, timestamp, max_iterations, tolerance, min_baseline, max_yaw_std, rate
    )
    if not solution.converged.all():
        warnings.warn(
            f"WLS did not converge in {max_iterations} Gauss-Newton iterations in "
            f"{int(np.count_nonzero(~solution.converged))} of {solution.converged.size} "
            "trials",
            ConvergenceWarning,
            stacklevel=2,
        )
    return solution


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
    """Solve the parent's pose from N >= 2 children by generalised least squares: one
    trial of :func:`solve_wls_batch`, raising and warning where the batch flags.

    Args:
        children_world: (N, 3) children's world positions, m.
        children_level: (N, 3) the children measured in the parent's levelled frame, m.
        cov_children_world: (3N, 3N) joint covariance of the world positions, m^2.
        cov_measurements: (N, 3, 3) covariance of each measurement, m^2.
        timestamp, max_iterations, tolerance, min_baseline, max_yaw_std,
            false_alarm_rate: as :func:`solve_wls_batch`'s.

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
        PoorGeometryWarning: the predicted yaw std exceeds ``max_yaw_std``.
    """
    rate = check_false_alarm_rate(false_alarm_rate)
    _check_iterations(max_iterations)
    w, m = check_cps_pair(children_world, children_level)
    n = w.shape[0]
    cw = check_covariance(cov_children_world, 3 * n, "cov_children_world")
    cm = check_measurement_covariances(cov_measurements, n)
    batch, step_norm = _solve(
        w[None],
        m[None],
        cw[None],
        cm[None],
        timestamp,
        max_iterations,
        tolerance,
        min_baseline,
        max_yaw_std,
        rate,
    )
    if batch.poor_geometry[0]:
        raise ValueError(coincide_message(batch.baseline[0], min_baseline))
    if not batch.converged[0]:
        warnings.warn(
            f"WLS did not converge in {max_iterations} Gauss-Newton iterations: last step "
            f"{step_norm[0]:.3g} (rad and m) above the tolerance {tolerance:g}",
            ConvergenceWarning,
            stacklevel=2,
        )
    solution = batch.trial(0)
    if batch.inconsistent[0]:
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
