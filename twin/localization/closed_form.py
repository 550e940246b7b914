"""The paper's closed-form CPS solution for two children (eq. 2 and the two lines after).

    phi = atan2(wy1 - wy2, wx1 - wx2) - atan2(my1 - my2, mx1 - mx2)
    t   = w1 - Rz(phi) m1

``w`` are the children's world positions (measured before the parent moved), ``m`` their
positions measured in the parent's levelled frame after it moved. The height of the
parent comes from child 1 alone and the children's heights do not enter the yaw.

Two children give six equations for four unknowns. The two the closed form does not use
are checked: the horizontal baseline length ``|dw_xy| - |dm_xy|`` and the height difference
``dw_z - dm_z`` (``d = child 1 - child 2``) must vanish within their predicted covariance.
Their chi-square (2 degrees of freedom) is reported in :attr:`CpsSolution.chi2`, and
:class:`InconsistentChildrenError` is raised above its quantile at ``false_alarm_rate``
(see :mod:`twin.instruments.consistency`). A child that moved along the baseline or
vertically is caught; one that moved across the baseline only rotates the baseline, which
two children cannot tell from a yaw change (a third child can: use WLS).

:func:`solve_closed_form_batch` solves T trials at once and flags what it cannot solve or
finds inconsistent (:class:`CpsSolutionBatch`); :func:`solve_closed_form` is its one-trial
form, which raises and warns where the batch flags.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.rotation import rot_z, rot_z_derivative, wrap_angle
from twin.instruments.consistency import (
    DEFAULT_FALSE_ALARM_RATE,
    check_false_alarm_rate,
    chi2_statistic_batch,
    exceeds_threshold,
    raise_if_inconsistent,
)
from twin.instruments.errors import InconsistentChildrenError
from twin.localization.input_checks import (
    DEFAULT_MAX_YAW_STD,
    DEFAULT_MIN_BASELINE,
    check_covariance,
    check_cps_input_batch,
    check_cps_pair,
    check_measurement_covariances,
    coincide_message,
    poor_geometry,
    substitute_trials,
)
from twin.localization.pose import CpsSolution, CpsSolutionBatch, ParentPoseBatch, warn_if_poor


def _perpendicular(d: NDArray[np.float64]) -> NDArray[np.float64]:
    """(T, 3) vectors -> (T, 3) ``(-dy, dx, 0) / (dx^2 + dy^2)``: d atan2(dy, dx) / d d."""
    out = np.zeros(d.shape)
    out[:, 0], out[:, 1] = -d[:, 1], d[:, 0]
    # float_power rounds the squares as Python's ** does (np.square may differ in the
    # last bit), so that the stored runs' Jacobians keep every bit.
    square = np.float_power(d[:, :2], 2)
    return out / (square[:, 0] + square[:, 1])[:, None]


def closed_form_pose_batch(
    children_world: NDArray[np.float64], children_level: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(T,) yaws (rad, in [-pi, pi)) and (T, 3) translations (m) from (T, 2, 3) world and
    levelled positions of two children, without input checks."""
    dw = children_world[:, 0] - children_world[:, 1]
    dm = children_level[:, 0] - children_level[:, 1]
    yaw = wrap_angle(np.arctan2(dw[:, 1], dw[:, 0]) - np.arctan2(dm[:, 1], dm[:, 0]))
    return yaw, children_world[:, 0] - (rot_z(yaw) @ children_level[:, 0, :, None])[..., 0]


def closed_form_jacobians_batch(
    children_world: NDArray[np.float64],
    children_level: NDArray[np.float64],
    yaw: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """First-order sensitivities of the closed form in T trials.

    Returns:
        ``(g_world, g_level)``: (T, 4, 6) derivatives of (yaw, x, y, z) with respect to the
        stacked world positions (w1, w2) and the stacked measurements (m1, m2).
    """
    n_trials = yaw.shape[0]
    a = _perpendicular(children_world[:, 0] - children_world[:, 1])
    b = _perpendicular(children_level[:, 0] - children_level[:, 1])
    dyaw_dw = np.concatenate([a, -a], axis=-1)
    dyaw_dm = np.concatenate([-b, b], axis=-1)
    lever = (rot_z_derivative(yaw) @ children_level[:, 0, :, None])[..., 0]  # d(R m1)/d yaw
    g_world = np.zeros((n_trials, 4, 6))
    g_world[:, 0] = dyaw_dw
    g_world[:, 1:, :3] = np.eye(3)
    g_world[:, 1:] -= lever[:, :, None] * dyaw_dw[:, None, :]
    g_level = np.zeros((n_trials, 4, 6))
    g_level[:, 0] = dyaw_dm
    g_level[:, 1:, :3] = -rot_z(yaw)
    g_level[:, 1:] -= lever[:, :, None] * dyaw_dm[:, None, :]
    return g_world, g_level


def closed_form_redundancy_batch(
    children_world: NDArray[np.float64],
    children_level: NDArray[np.float64],
    cov_world: NDArray[np.float64],
    cov_level: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The two equations the closed form leaves unused, and their covariance.

    Returns:
        ``(e, cov_e)``: (T, 2) baseline-length and height-difference mismatch, m, and their
        (T, 2, 2) covariance, m^2, from the (T, 6, 6) covariances of (w1, w2) and (m1, m2).
    """
    n_trials = children_world.shape[0]
    dw = children_world[:, 0] - children_world[:, 1]
    dm = children_level[:, 0] - children_level[:, 1]
    lw, lm = np.hypot(dw[:, 0], dw[:, 1]), np.hypot(dm[:, 0], dm[:, 1])
    e = np.empty((n_trials, 2))
    e[:, 0], e[:, 1] = lw - lm, dw[:, 2] - dm[:, 2]
    jac_w = np.zeros((n_trials, 2, 6))
    jac_w[:, 0, :2] = dw[:, :2] / lw[:, None]
    jac_w[:, 0, 3:5] = -dw[:, :2] / lw[:, None]
    jac_w[:, 1, 2], jac_w[:, 1, 5] = 1.0, -1.0
    jac_m = np.zeros((n_trials, 2, 6))
    jac_m[:, 0, :2] = -dm[:, :2] / lm[:, None]
    jac_m[:, 0, 3:5] = dm[:, :2] / lm[:, None]
    jac_m[:, 1, 2], jac_m[:, 1, 5] = -1.0, 1.0
    cov = jac_w @ cov_world @ jac_w.mT + jac_m @ cov_level @ jac_m.mT
    return e, cov


def _solve(
    w: NDArray[np.float64],
    m: NDArray[np.float64],
    cw: NDArray[np.float64],
    cm: NDArray[np.float64],
    timestamp: float,
    min_baseline: float,
    max_yaw_std: float,
    rate: float | None,
) -> tuple[CpsSolutionBatch, NDArray[np.float64]]:
    """The closed form of checked (T, 2, 3) points and (T, 6, 6) covariances; returns the
    solutions and the (T, 2) mismatch of the unused equations, m."""
    baseline, bad = poor_geometry(w, m, min_baseline)
    w, m, cw, cm = substitute_trials(bad, w, m, cw, cm)
    yaw, t = closed_form_pose_batch(w, m)
    g_world, g_level = closed_form_jacobians_batch(w, m, yaw)
    cov = g_world @ cw @ g_world.mT + g_level @ cm @ g_level.mT
    cov = 0.5 * (cov + cov.mT)
    mismatch, cov_mismatch = closed_form_redundancy_batch(w, m, cw, cm)
    chi2 = chi2_statistic_batch(mismatch, cov_mismatch)
    if bad.any():
        for arr in (yaw, t, cov, g_world, g_level, chi2):
            arr[bad] = np.nan
    pose = ParentPoseBatch(yaw, t, cov, timestamp)
    n_trials = yaw.shape[0]
    solution = CpsSolutionBatch(
        pose=pose,
        method="closed_form",
        children_jacobian=g_world,
        measurement_jacobian=g_level,
        baseline=baseline,
        chi2=chi2,
        dof=2,
        iterations=np.zeros(n_trials, dtype=np.int64),
        converged=np.ones(n_trials, dtype=bool),
        inconsistent=exceeds_threshold(chi2, 2, rate) & ~bad,
        poor_geometry=bad,
        poor_yaw=pose.yaw_std > max_yaw_std,
    )
    return solution, mismatch


def solve_closed_form_batch(
    children_world: ArrayLike,
    children_level: ArrayLike,
    cov_children_world: ArrayLike | None = None,
    cov_measurements: ArrayLike | None = None,
    *,
    timestamp: float = 0.0,
    min_baseline: float = DEFAULT_MIN_BASELINE,
    max_yaw_std: float = DEFAULT_MAX_YAW_STD,
    false_alarm_rate: float | None = DEFAULT_FALSE_ALARM_RATE,
) -> CpsSolutionBatch:
    """The paper's closed form with first-order covariance and a consistency test, in
    each of T trials.

    Args:
        children_world: (T, 2, 3) world positions of the two children, m.
        children_level: (T, 2, 3) their positions measured from the parent's new station,
            in its levelled frame, m.
        cov_children_world: (T, 6, 6) joint covariance of the world positions, m^2 (keep
            the cross terms: both children inherit the same earlier parent error); None = 0.
        cov_measurements: (T, 2, 3, 3) covariance of each measurement, m^2; None = 0.
        timestamp: time of the solutions, s.
        min_baseline: smallest accepted horizontal baseline, m.
        max_yaw_std: predicted yaw std, rad, above which ``poor_yaw`` is set.
        false_alarm_rate: probability that consistent data set ``inconsistent``; None
            switches the test off (chi2 is still reported). Without covariances the data
            are taken as exact: any mismatch above a few nanometres is inconsistent.

    Returns:
        The solutions with their covariances, Jacobians and chi-square, and the flags
        ``inconsistent``, ``poor_geometry`` (no solution: NaN) and ``poor_yaw``.

    Raises:
        ValueError: not exactly two children, wrong shapes, a covariance that is not
            symmetric positive semidefinite.
    """
    rate = check_false_alarm_rate(false_alarm_rate)
    w, m, cw, cm = check_cps_input_batch(
        children_world, children_level, cov_children_world, cov_measurements
    )
    if w.shape[1] != 2:
        raise ValueError(
            f"the closed form uses exactly two children, got {w.shape[1]}; use "
            "solve_wls_batch for more"
        )
    return _solve(w, m, cw, cm, timestamp, min_baseline, max_yaw_std, rate)[0]


def solve_closed_form(
    children_world: ArrayLike,
    children_level: ArrayLike,
    cov_children_world: ArrayLike | None = None,
    cov_measurements: ArrayLike | None = None,
    *,
    timestamp: float = 0.0,
    min_baseline: float = DEFAULT_MIN_BASELINE,
    max_yaw_std: float = DEFAULT_MAX_YAW_STD,
    false_alarm_rate: float | None = DEFAULT_FALSE_ALARM_RATE,
) -> CpsSolution:
    """The closed form of one trial (:func:`solve_closed_form_batch`), raising and warning
    where the batch flags.

    Args:
        children_world: (2, 3) world positions of the two children, m.
        children_level: (2, 3) their positions measured from the parent's new station, in
            its levelled frame, m.
        cov_children_world: (6, 6) joint covariance of the world positions, m^2; None = 0.
        cov_measurements: (2, 3, 3) covariance of each measurement, m^2; None = 0.
        timestamp, min_baseline, max_yaw_std, false_alarm_rate: as
            :func:`solve_closed_form_batch`'s.

    Raises:
        InconsistentChildrenError: the unused equations disagree beyond their noise (a
            child moved, or a wrong prism); ``details`` hold ``chi2``, ``dof``,
            ``threshold``, ``mismatch`` (m) and the rejected ``solution``.
        ValueError: not exactly two children, NaN, children coinciding horizontally, a
            covariance that is not symmetric positive semidefinite.

    Warns:
        PoorGeometryWarning: the predicted yaw std exceeds ``max_yaw_std``.
    """
    rate = check_false_alarm_rate(false_alarm_rate)
    w, m = check_cps_pair(children_world, children_level)
    if w.shape[0] != 2:
        raise ValueError(
            f"the closed form uses exactly two children, got {w.shape[0]}; use solve_wls for more"
        )
    cw = (
        np.zeros((6, 6))
        if cov_children_world is None
        else check_covariance(cov_children_world, 6, "cov_children_world")
    )
    cm = check_measurement_covariances(cov_measurements, 2)
    batch, mismatch = _solve(
        w[None], m[None], cw[None], cm[None], timestamp, min_baseline, max_yaw_std, rate
    )
    if batch.poor_geometry[0]:
        raise ValueError(coincide_message(batch.baseline[0], min_baseline))
    solution = batch.trial(0)
    if batch.inconsistent[0]:
        assert solution.chi2 is not None
        raise_if_inconsistent(
            solution.chi2,
            solution.dof,
            rate,
            InconsistentChildrenError,
            f"the two children do not fit their world positions (baseline length differs by "
            f"{mismatch[0, 0] * 1e3:.1f} mm, height difference by {mismatch[0, 1] * 1e3:.1f} "
            "mm; a child moved or a wrong prism)",
            mismatch=mismatch[0],
            solution=solution,
        )
    warn_if_poor(solution, max_yaw_std)
    return solution
