"""Points measured by the parent, mapped to the world with the parent's uncertainty.

``p_W = Rz(yaw) p_L + t`` (paper eq. 1). To first order

    d p_W = [dRz/dyaw p_L, I] d(yaw, t) + Rz d p_L,

so points measured from one station share the parent's error: their world covariance is a
joint (3N, 3N) matrix with cross terms. Feed it to
:func:`twin.instruments.marker_pose.fit_marker_pose` to get LED world positions whose
covariance includes the parent's pose uncertainty.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.rotation import rot_z, rot_z_derivative
from twin.localization.pose import ParentPose


def level2world_jacobian(yaw: float, points_level: ArrayLike) -> NDArray[np.float64]:
    """(N, 3, 4) derivative of world points with respect to the parent's (yaw, t)."""
    p = np.asarray(points_level, dtype=float).reshape(-1, 3)
    jac = np.zeros((p.shape[0], 3, 4))
    jac[:, :, 0] = p @ rot_z_derivative(yaw).T
    jac[:, :, 1:] = np.eye(3)
    return jac


def level2world_with_covariance(
    pose: ParentPose, points_level: ArrayLike, cov_level: ArrayLike | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Map points measured in the parent's levelled frame to the world, with covariance.

    Args:
        pose: the parent's pose estimate and its (4, 4) covariance.
        points_level: (N, 3) measured points, m.
        cov_level: (N, 3, 3) independent measurement covariances, m^2; None = 0.

    Returns:
        ``(points_world, covariance)``: (N, 3) m and the joint (3N, 3N) covariance, m^2,
        including the parent's pose uncertainty shared by all points.
    """
    p = np.asarray(points_level, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or not np.all(np.isfinite(p)):
        raise ValueError(f"points_level must be a finite (N, 3) array, got shape {p.shape}")
    n = p.shape[0]
    rot = rot_z(pose.yaw)
    jac = level2world_jacobian(pose.yaw, p).reshape(3 * n, 4)
    cov = jac @ pose.covariance @ jac.T
    if cov_level is not None:
        c = np.asarray(cov_level, dtype=float)
        if c.shape != (n, 3, 3) or not np.all(np.isfinite(c)):
            raise ValueError(f"cov_level must be a finite ({n}, 3, 3) array, got {c.shape}")
        for i in range(n):
            cov[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] += rot @ c[i] @ rot.T
    return pose.level2world(p), 0.5 * (cov + cov.T)
