"""Rotations and angles: the one home of the project's rotation helpers (the camera model,
the instruments, positioning and the simulator all use these), built on
:mod:`scipy.spatial.transform` where it serves.

- :func:`skew`, :func:`rot_z`, :func:`rot_z_derivative`, :func:`wrap_angle`: small
  helpers over arrays of any leading shape.
- Conversions between representations follow the ``a2b`` pattern: :func:`euler2matrix`,
  :func:`matrix2euler`, :func:`rotvec2matrix`, :func:`matrix2rotvec`;
  :func:`rotvec2matrix_batch` and :func:`right_jacobian_batch` take stacks of vectors.

Tsai's convention (and the paper's Table II) gives the world-to-camera rotation as angles
(rx, ry, rz) about the fixed world axes X, Y, Z applied in that order:

    R_world2cam = Rz(rz) @ Ry(ry) @ Rx(rx)

which is scipy's extrinsic ``"xyz"`` sequence.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

EULER_SEQ = "xyz"


def euler2matrix(angles_rad: ArrayLike) -> NDArray[np.float64]:
    """(3,) angles about X, Y, Z in radians -> (3, 3) rotation Rz @ Ry @ Rx."""
    return Rotation.from_euler(EULER_SEQ, np.asarray(angles_rad, dtype=float)).as_matrix()


def matrix2euler(rotation: ArrayLike) -> NDArray[np.float64]:
    """(3, 3) rotation -> (3,) angles about X, Y, Z in radians, each in (-pi, pi]."""
    return Rotation.from_matrix(np.asarray(rotation, dtype=float)).as_euler(EULER_SEQ)


def skew(v: ArrayLike) -> NDArray[np.float64]:
    """(..., 3) vectors -> (..., 3, 3) cross-product matrices [v]x, so that
    ``skew(a) @ b = a x b``."""
    a = np.asarray(v, dtype=float)
    if a.shape[-1:] != (3,):
        raise ValueError(f"skew takes (..., 3) vectors, got shape {a.shape}")
    if a.ndim == 1:  # one vector: as fast as a matrix literal
        x, y, z = a
        return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    x, y, z = a[..., 0], a[..., 1], a[..., 2]
    out = np.zeros((*a.shape[:-1], 3, 3))
    out[..., 0, 1], out[..., 0, 2] = -z, y
    out[..., 1, 0], out[..., 1, 2] = z, -x
    out[..., 2, 0], out[..., 2, 1] = -y, x
    return out


def rot_z(yaw: ArrayLike) -> NDArray[np.float64]:
    """Rotation about z by (...,) angles, rad -> (..., 3, 3)."""
    a = np.asarray(yaw, dtype=float)
    c, s = np.cos(a), np.sin(a)
    if a.ndim == 0:
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    out = np.zeros((*a.shape, 3, 3))
    out[..., 0, 0], out[..., 0, 1] = c, -s
    out[..., 1, 0], out[..., 1, 1] = s, c
    out[..., 2, 2] = 1.0
    return out


def rot_z_derivative(yaw: ArrayLike) -> NDArray[np.float64]:
    """d Rz / d yaw at (...,) angles -> (..., 3, 3)."""
    a = np.asarray(yaw, dtype=float)
    c, s = np.cos(a), np.sin(a)
    if a.ndim == 0:
        return np.array([[-s, -c, 0.0], [c, -s, 0.0], [0.0, 0.0, 0.0]])
    out = np.zeros((*a.shape, 3, 3))
    out[..., 0, 0], out[..., 0, 1] = -s, -c
    out[..., 1, 0], out[..., 1, 1] = c, -s
    return out


def wrap_angle(angle: ArrayLike) -> NDArray[np.float64] | float:
    """Angles, rad, wrapped to [-pi, pi): a float for a float, else an array of the
    input's shape (the same values either way: Python's ``%`` and ``np.mod`` round alike).
    """
    if isinstance(angle, float):
        return (angle + math.pi) % (2.0 * math.pi) - math.pi
    return np.mod(np.asarray(angle, dtype=float) + np.pi, 2.0 * np.pi) - np.pi


def compose_planar(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Planar pose ``a (x) b``: the (3,) pose (x m, y m, yaw rad) ``b``, given in the frame
    of pose ``a``, expressed in the frame ``a`` is given in. The yaw is not wrapped."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2]])


def invert_planar(a: ArrayLike) -> NDArray[np.float64]:
    """The (3,) planar pose that undoes ``a``: ``compose_planar(invert_planar(a), a)`` is
    the identity."""
    a = np.asarray(a, dtype=float)
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([-(c * a[0] + s * a[1]), s * a[0] - c * a[1], -a[2]])


def rotvec2matrix(rotvec: ArrayLike) -> NDArray[np.float64]:
    """(3,) rotation vector, rad -> (3, 3) rotation matrix (Rodrigues' formula)."""
    w = np.asarray(rotvec, dtype=float)
    theta2 = float(w @ w)
    k = skew(w)
    if theta2 < 1e-12:
        # Taylor expansion: sin(t)/t ~ 1 - t^2/6, (1 - cos t)/t^2 ~ 1/2 - t^2/24.
        a, b = 1.0 - theta2 / 6.0, 0.5 - theta2 / 24.0
    else:
        theta = np.sqrt(theta2)
        a, b = np.sin(theta) / theta, (1.0 - np.cos(theta)) / theta2
    return np.eye(3) + a * k + b * (k @ k)


def right_jacobian(rotvec: ArrayLike) -> NDArray[np.float64]:
    """(3, 3) right Jacobian J_r of SO(3) at a rotation vector.

    exp(w + d) ~ exp(w) exp(J_r(w) d) for a small d, so the derivative of R(w) @ v with
    respect to w is -R(w) @ skew(v) @ J_r(w).
    """
    w = np.asarray(rotvec, dtype=float)
    theta2 = float(w @ w)
    k = skew(w)
    if theta2 < 1e-12:
        a, b = 0.5 - theta2 / 24.0, 1.0 / 6.0 - theta2 / 120.0
    else:
        theta = np.sqrt(theta2)
        a = (1.0 - np.cos(theta)) / theta2
        b = (theta - np.sin(theta)) / (theta2 * theta)
    return np.eye(3) - a * k + b * (k @ k)


def rotvec2matrix_batch(rotvecs: ArrayLike) -> NDArray[np.float64]:
    """(..., 3) rotation vectors, rad -> (..., 3, 3) rotation matrices (Rodrigues' formula).

    The formula of :func:`rotvec2matrix` elementwise, with ``K^2 = w w^T - theta^2 I``; each
    matrix depends on its own vector only.
    """
    w = np.asarray(rotvecs, dtype=float)
    theta2 = np.sum(w * w, axis=-1)
    near = theta2 < 1e-12
    theta = np.sqrt(np.where(near, 1.0, theta2))
    a = np.where(near, 1.0 - theta2 / 6.0, np.sin(theta) / theta)
    b = np.where(near, 0.5 - theta2 / 24.0, (1.0 - np.cos(theta)) / np.where(near, 1.0, theta2))
    return _identity_plus(w, theta2, a, b)


def right_jacobian_batch(rotvecs: ArrayLike) -> NDArray[np.float64]:
    """(..., 3) rotation vectors, rad -> (..., 3, 3) right Jacobians of SO(3), elementwise
    (see :func:`right_jacobian`)."""
    w = np.asarray(rotvecs, dtype=float)
    theta2 = np.sum(w * w, axis=-1)
    near = theta2 < 1e-12
    t2 = np.where(near, 1.0, theta2)
    theta = np.sqrt(t2)
    a = np.where(near, 0.5 - theta2 / 24.0, (1.0 - np.cos(theta)) / t2)
    b = np.where(near, 1.0 / 6.0 - theta2 / 120.0, (theta - np.sin(theta)) / (t2 * theta))
    return _identity_plus(w, theta2, -a, b)


def _identity_plus(
    w: NDArray[np.float64], theta2: NDArray[np.float64], a: NDArray[np.float64], b: NDArray
) -> NDArray[np.float64]:
    """I + a [w]x + b [w]x^2 for (..., 3) vectors w and (...,) coefficients a, b."""
    k2 = w[..., :, None] * w[..., None, :] - theta2[..., None, None] * np.eye(3)
    return np.eye(3) + a[..., None, None] * skew(w) + b[..., None, None] * k2


def matrix2rotvec(rotation: ArrayLike) -> NDArray[np.float64]:
    """(3, 3) rotation matrix -> (3,) rotation vector, rad."""
    return Rotation.from_matrix(np.asarray(rotation, dtype=float)).as_rotvec()


def nearest_rotation(m: ArrayLike) -> NDArray[np.float64]:
    """The rotation matrix closest (Frobenius) to a (3, 3) matrix, by SVD."""
    u, _, vt = np.linalg.svd(np.asarray(m, dtype=float))
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def rotation_angle_between(r_a: ArrayLike, r_b: ArrayLike) -> float:
    """Angle (rad) of the rotation taking ``r_a`` to ``r_b``; both (3, 3)."""
    rel = Rotation.from_matrix(np.asarray(r_a) @ np.asarray(r_b).T)
    return float(rel.magnitude())


def look_at_world2cam(view_direction: ArrayLike, up: ArrayLike = (0.0, 0.0, 1.0)) -> NDArray:
    """World-to-camera rotation of a camera looking along ``view_direction``.

    The camera frame is OpenCV's: x right, y down, z forward. The image's "up" (-y) is
    aligned with the projection of ``up`` onto the image plane.

    Args:
        view_direction: (3,) direction of the optical axis in the world frame.
        up: (3,) world direction that should appear up in the image.

    Returns:
        (3, 3) rotation matrix mapping world vectors to camera vectors.
    """
    z = np.asarray(view_direction, dtype=float)
    if not np.all(np.isfinite(z)) or np.linalg.norm(z) == 0:
        raise ValueError(f"view_direction must be a finite non-zero vector, got {z}")
    z = z / np.linalg.norm(z)
    up = np.asarray(up, dtype=float)
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-9:
        raise ValueError(f"view_direction {z} is parallel to up {up}; give another up vector")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.vstack([x, y, z])
