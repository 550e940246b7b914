"""Rotation about the vertical and the parent's levelled-frame-to-world map (paper eq. 1).

Thanks to tilt compensation the parent's pose is a yaw ``phi`` about the world z-axis and a
translation ``t``: a point measured in the parent's levelled instrument frame L maps to the
world W by ``p_W = Rz(phi) @ p_L + t``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def rot_z(yaw: ArrayLike) -> NDArray[np.float64]:
    """Rotation about z by (...,) angles, rad -> (..., 3, 3)."""
    a = np.asarray(yaw, dtype=float)
    c, s = np.cos(a), np.sin(a)
    if a.ndim == 0:
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    zero, one = np.zeros_like(c), np.ones_like(c)
    rows = [[c, -s, zero], [s, c, zero], [zero, zero, one]]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def rot_z_derivative(yaw: ArrayLike) -> NDArray[np.float64]:
    """d Rz / d yaw at (...,) angles -> (..., 3, 3)."""
    a = np.asarray(yaw, dtype=float)
    c, s = np.cos(a), np.sin(a)
    if a.ndim == 0:
        return np.array([[-s, -c, 0.0], [c, -s, 0.0], [0.0, 0.0, 0.0]])
    zero = np.zeros_like(c)
    rows = [[-s, -c, zero], [c, -s, zero], [zero, zero, zero]]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def wrap_angle(angle: ArrayLike) -> NDArray[np.float64]:
    """Wrap (...,) angles, rad, to [-pi, pi)."""
    return np.mod(np.asarray(angle, dtype=float) + np.pi, 2.0 * np.pi) - np.pi


def level2world(points_level: ArrayLike, yaw: float, translation: ArrayLike) -> NDArray:
    """Paper eq. (1): (..., 3) points in the parent's levelled frame -> world, m."""
    p = np.asarray(points_level, dtype=float)
    return p @ rot_z(yaw).T + np.asarray(translation, dtype=float)


def world2level(points_world: ArrayLike, yaw: float, translation: ArrayLike) -> NDArray:
    """Inverse of :func:`level2world`: (..., 3) world points -> levelled frame, m."""
    p = np.asarray(points_world, dtype=float) - np.asarray(translation, dtype=float)
    return p @ rot_z(yaw)
