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
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.rotation import rot_z, rot_z_derivative, wrap_angle
from twin.instruments.consistency import (
    DEFAULT_FALSE_ALARM_RATE,
    check_false_alarm_rate,
    chi2_statistic,
    raise_if_inconsistent,
)
from twin.instruments.errors import InconsistentChildrenError
from twin.localization.input_checks import (
    DEFAULT_MAX_YAW_STD,
    DEFAULT_MIN_BASELINE,
    check_covariance,
    check_cps_input,
    check_measurement_covariances,
)
from twin.localization.pose import CpsSolution, ParentPose, warn_if_poor


def closed_form_pose(
    children_world: NDArray[np.float64], children_level: NDArray[np.float64]
) -> tuple[float, NDArray[np.float64]]:
    """Yaw (rad, in [-pi, pi)) and (3,) translation (m) from (2, 3) world and levelled
    positions of two children, without input checks."""
    dw = children_world[0] - children_world[1]
    dm = children_level[0] - children_level[1]
    yaw = float(wrap_angle(np.arctan2(dw[1], dw[0]) - np.arctan2(dm[1], dm[0])))
    return yaw, children_world[0] - rot_z(yaw) @ children_level[0]


def closed_form_jacobians(
    children_world: NDArray[np.float64],
    children_level: NDArray[np.float64],
    yaw: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """First-order sensitivities of the closed form.

    Returns:
        ``(g_world, g_level)``: (4, 6) derivatives of (yaw, x, y, z) with respect to the
        stacked world positions (w1, w2) and the stacked measurements (m1, m2).
    """
    dw = children_world[0] - children_world[1]
    dm = children_level[0] - children_level[1]
    a = np.array([-dw[1], dw[0], 0.0]) / (dw[0] ** 2 + dw[1] ** 2)
    b = np.array([-dm[1], dm[0], 0.0]) / (dm[0] ** 2 + dm[1] ** 2)
    dyaw_dw = np.concatenate([a, -a])
    dyaw_dm = np.concatenate([-b, b])
    lever = rot_z_derivative(yaw) @ children_level[0]  # d(R m1)/d yaw
    g_world = np.zeros((4, 6))
    g_world[0] = dyaw_dw
    g_world[1:, :3] = np.eye(3)
    g_world[1:] -= np.outer(lever, dyaw_dw)
    g_level = np.zeros((4, 6))
    g_level[0] = dyaw_dm
    g_level[1:, :3] = -rot_z(yaw)
    g_level[1:] -= np.outer(lever, dyaw_dm)
    return g_world, g_level


def closed_form_redundancy(
    children_world: NDArray[np.float64],
    children_level: NDArray[np.float64],
    cov_world: NDArray[np.float64],
    cov_level: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The two equations the closed form leaves unused, and their covariance.

    Returns:
        ``(e, cov_e)``: (2,) baseline-length and height-difference mismatch, m, and their
        (2, 2) covariance, m^2, from the (6, 6) covariances of (w1, w2) and (m1, m2).
    """
    dw = children_world[0] - children_world[1]
    dm = children_level[0] - children_level[1]
    lw, lm = np.hypot(dw[0], dw[1]), np.hypot(dm[0], dm[1])
    e = np.array([lw - lm, dw[2] - dm[2]])
    jac_w = np.zeros((2, 6))
    jac_w[0, :2] = dw[:2] / lw
    jac_w[0, 3:5] = -dw[:2] / lw
    jac_w[1, 2], jac_w[1, 5] = 1.0, -1.0
    jac_m = np.zeros((2, 6))
    jac_m[0, :2] = -dm[:2] / lm
    jac_m[0, 3:5] = dm[:2] / lm
    jac_m[1, 2], jac_m[1, 5] = -1.0, 1.0
    return e, jac_w @ cov_world @ jac_w.T + jac_m @ cov_level @ jac_m.T


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
    """The paper's closed form with first-order covariance and a consistency test.

    Args:
        children_world: (2, 3) world positions of the two children, m.
        children_level: (2, 3) their positions measured from the parent's new station, in
            its levelled frame, m.
        cov_children_world: (6, 6) joint covariance of the world positions, m^2 (keep the
            cross terms: both children inherit the same earlier parent error); None = 0.
        cov_measurements: (2, 3, 3) covariance of each measurement, m^2; None = 0.
        timestamp: time of the solution, s.
        min_baseline: smallest accepted horizontal baseline, m.
        max_yaw_std: predicted yaw std, rad, above which :class:`PoorGeometryWarning` is
            raised.
        false_alarm_rate: probability that consistent data raise
            :class:`InconsistentChildrenError`; None switches the test off (chi2 is still
            reported). Without covariances the data are taken as exact: any mismatch above
            a few nanometres is inconsistent.

    Raises:
        InconsistentChildrenError: the unused equations disagree beyond their noise (a
            child moved, or a wrong prism); ``details`` hold ``chi2``, ``dof``,
            ``threshold``, ``mismatch`` (m) and the rejected ``solution``.
        ValueError: not exactly two children, NaN, children coinciding horizontally, a
            covariance that is not symmetric positive semidefinite.
    """
    rate = check_false_alarm_rate(false_alarm_rate)
    w, m, baseline = check_cps_input(children_world, children_level, min_baseline)
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
    yaw, t = closed_form_pose(w, m)
    g_world, g_level = closed_form_jacobians(w, m, yaw)
    cov = g_world @ cw @ g_world.T + g_level @ cm @ g_level.T
    mismatch, cov_mismatch = closed_form_redundancy(w, m, cw, cm)
    solution = CpsSolution(
        pose=ParentPose(yaw, t, 0.5 * (cov + cov.T), timestamp),
        method="closed_form",
        children_jacobian=g_world,
        measurement_jacobian=g_level,
        baseline=baseline,
        chi2=chi2_statistic(mismatch, cov_mismatch),
        dof=2,
    )
    assert solution.chi2 is not None
    raise_if_inconsistent(
        solution.chi2,
        solution.dof,
        rate,
        InconsistentChildrenError,
        f"the two children do not fit their world positions (baseline length differs by "
        f"{mismatch[0] * 1e3:.1f} mm, height difference by {mismatch[1] * 1e3:.1f} mm; a "
        "child moved or a wrong prism)",
        mismatch=mismatch,
        solution=solution,
    )
    warn_if_poor(solution, max_yaw_std)
    return solution
