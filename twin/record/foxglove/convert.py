"""Plain values (s, m, rotation matrices, 0..1 colours) as Foxglove's message parts."""

from __future__ import annotations

import math

import numpy as np
from foxglove.messages import Color, Point3, Pose, Quaternion, Timestamp, Vector3
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation


def timestamp(t: float) -> Timestamp:
    """Seconds on the campaign's clock (at least 0) as a Foxglove timestamp."""
    ns = max(0, round(float(t) * 1e9))
    return Timestamp(sec=ns // 1_000_000_000, nsec=ns % 1_000_000_000)


def vector3(v: ArrayLike) -> Vector3:
    """(3,) as a Vector3 (m)."""
    x, y, z = (float(c) for c in np.asarray(v, dtype=float).reshape(3))
    return Vector3(x=x, y=y, z=z)


def point3(v: ArrayLike) -> Point3:
    """(3,) as a Point3 (m)."""
    x, y, z = (float(c) for c in np.asarray(v, dtype=float).reshape(3))
    return Point3(x=x, y=y, z=z)


def quaternion(rotation: ArrayLike) -> Quaternion:
    """A (3, 3) rotation matrix (child frame to parent frame) as a unit quaternion."""
    x, y, z, w = Rotation.from_matrix(np.asarray(rotation, dtype=float)).as_quat()
    return Quaternion(x=float(x), y=float(y), z=float(z), w=float(w))


def yaw_quaternion(yaw: float) -> Quaternion:
    """A rotation of ``yaw`` rad about z."""
    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0))


def pose(position: ArrayLike, rotation: ArrayLike | None = None) -> Pose:
    """A pose at ``position`` (3,) m, rotated by ``rotation`` (3, 3) (identity if None)."""
    q = Quaternion(x=0.0, y=0.0, z=0.0, w=1.0) if rotation is None else quaternion(rotation)
    return Pose(position=vector3(position), orientation=q)


def color(r: float, g: float, b: float, a: float = 1.0) -> Color:
    """A colour from 0..1 components."""
    return Color(r=float(r), g=float(g), b=float(b), a=float(a))


def ramp(value: float, full: float) -> Color:
    """Green at 0, yellow at ``full / 2``, red at ``full`` and beyond (grey for NaN)."""
    if not math.isfinite(value) or full <= 0:
        return color(0.6, 0.6, 0.6)
    s = min(max(value / full, 0.0), 1.0)
    return color(min(1.0, 2.0 * s), min(1.0, 2.0 * (1.0 - s)), 0.0)
