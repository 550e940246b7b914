"""The paper's closed-form CPS (eq. 2) in T trials at once: :mod:`.closed_form` over arrays.

Per trial the same formulas as :func:`twin.localization.closed_form.solve_closed_form`:
the yaw from the two baselines, the translation from child 1, the first-order Jacobians
and covariance, and the chi-square (2 degrees of freedom) of the baseline-length and
height-difference mismatch. What the scalar solver raises or warns for one trial's data
is a flag of :class:`twin.localization.pose_batch.CpsSolutionBatch`.
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
)
from twin.localization.input_checks import DEFAULT_MAX_YAW_STD, DEFAULT_MIN_BASELINE
from twin.localization.input_checks_batch import (
    check_cps_input_batch,
    poor_geometry,
    substitute_trials,
)
from twin.localization.pose_batch import CpsSolutionBatch, ParentPoseBatch


def _transpose(a: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.swapaxes(a, -1, -2)


def _perpendicular(d: NDArray[np.float64]) -> NDArray[np.float64]:
    """(T, 3) vectors -> (T, 3) ``(-dy, dx, 0) / (dx^2 + dy^2)``: d atan2(dy, dx) / d d."""
    out = np.zeros(d.shape)
    out[:, 0], out[:, 1] = -d[:, 1], d[:, 0]
    return out / (d[:, 0] ** 2 + d[:, 1] ** 2)[:, None]


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
    """(T, 4, 6) derivatives of (yaw, x, y, z) with respect to the stacked world positions
    (w1, w2) and the stacked measurements (m1, m2), as
    :func:`twin.localization.closed_form.closed_form_jacobians`."""
    n_trials = yaw.shape[0]
    a = _perpendicular(children_world[:, 0] - children_world[:, 1])
    b = _perpendicular(children_level[:, 0] - children_level[:, 1])
    dyaw_dw = np.concatenate([a, -a], axis=-1)
    dyaw_dm = np.concatenate([-b, b], axis=-1)
    lever = (rot_z_derivative(yaw) @ children_level[:, 0, :, None])[..., 0]
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
    """(T, 2) baseline-length and height-difference mismatch, m, and their (T, 2, 2)
    covariance, m^2, from the (T, 6, 6) covariances of (w1, w2) and (m1, m2)."""
    n_trials = children_world.shape[0]
    dw = children_world[:, 0] - children_world[:, 1]
    dm = children_level[:, 0] - children_level[:, 1]
    lw, lm = np.hypot(dw[:, 0], dw[:, 1]), np.hypot(dm[:, 0], dm[:, 1])
    e = np.stack([lw - lm, dw[:, 2] - dm[:, 2]], axis=-1)
    jac_w = np.zeros((n_trials, 2, 6))
    jac_w[:, 0, :2] = dw[:, :2] / lw[:, None]
    jac_w[:, 0, 3:5] = -dw[:, :2] / lw[:, None]
    jac_w[:, 1, 2], jac_w[:, 1, 5] = 1.0, -1.0
    jac_m = np.zeros((n_trials, 2, 6))
    jac_m[:, 0, :2] = -dm[:, :2] / lm[:, None]
    jac_m[:, 0, 3:5] = dm[:, :2] / lm[:, None]
    jac_m[:, 1, 2], jac_m[:, 1, 5] = -1.0, 1.0
    cov = jac_w @ cov_world @ _transpose(jac_w) + jac_m @ cov_level @ _transpose(jac_m)
    return e, cov


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
        cov_children_world: (T, 6, 6) joint covariance of the world positions, m^2;
            None = 0.
        cov_measurements: (T, 2, 3, 3) covariance of each measurement, m^2; None = 0.
        timestamp: time of the solutions, s.
        min_baseline: smallest accepted horizontal baseline, m.
        max_yaw_std: predicted yaw std, rad, above which ``poor_yaw`` is set.
        false_alarm_rate: probability that consistent data set ``inconsistent``; None
            switches the test off (chi2 is still reported).

    Returns:
        Per trial what :func:`twin.localization.closed_form.solve_closed_form` returns, with
        flags where it raises or warns.

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
    baseline, bad = poor_geometry(w, m, min_baseline)
    w, m, cw, cm = substitute_trials(bad, w, m, cw, cm)
    yaw, t = closed_form_pose_batch(w, m)
    g_world, g_level = closed_form_jacobians_batch(w, m, yaw)
    cov = g_world @ cw @ _transpose(g_world) + g_level @ cm @ _transpose(g_level)
    cov = 0.5 * (cov + _transpose(cov))
    mismatch, cov_mismatch = closed_form_redundancy_batch(w, m, cw, cm)
    chi2 = chi2_statistic_batch(mismatch, cov_mismatch)
    for arr in (yaw, t, cov, g_world, g_level, chi2):
        arr[bad] = np.nan
    pose = ParentPoseBatch(yaw, t, cov, timestamp)
    n_trials = yaw.shape[0]
    return CpsSolutionBatch(
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
