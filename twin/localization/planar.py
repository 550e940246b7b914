"""Rotation about the vertical and the parent's levelled-frame-to-world map (paper eq. 1).

Thanks to tilt compensation the parent's pose is a yaw ``phi`` about the world z-axis and a
translation ``t``: a point measured in the parent's levelled instrument frame L maps to the
world W by ``p_W = Rz(phi) @ p_L + t``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.rotation import rot_z


def level2world(points_level: ArrayLike, yaw: float, translation: ArrayLike) -> NDArray:
    """Paper eq. (1): (..., 3) points in the parent's levelled frame -> world, m."""
    p = np.asarray(points_level, dtype=float)
    return p @ rot_z(yaw).T + np.asarray(translation, dtype=float)


def world2level(points_world: ArrayLike, yaw: float, translation: ArrayLike) -> NDArray:
    """Inverse of :func:`level2world`: (..., 3) world points -> levelled frame, m."""
    p = np.asarray(points_world, dtype=float) - np.asarray(translation, dtype=float)
    return p @ rot_z(yaw)
