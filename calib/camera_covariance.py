"""A Tsai camera's uncertainty in a frame-free parametrization, and the pixels' derivatives.

Tsai's reported parameters give the rotation as angles about the world axes, whose
covariance changes meaning with the camera's heading. Here a camera's error is written as
a small change of the camera itself (:data:`CAMERA_PARAMETERS`):

- its intrinsics f, cx, cy (px), sx, kappa1 (1/px^2), added to;
- a turn about its own axes (a rotation vector, rad) and a shift of its optical centre in
  the world (m), as :func:`calib.pose_change.moved_camera` moves a camera.

A covariance in these terms can be carried with the camera (its JSON file), propagated to
the pixels of any point (:func:`camera_jacobian`), and moved with the world: a rigid
motion of the world frame turns the shift and leaves the rest alone.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.camera import TsaiCamera
from calib.covariance import central_jacobian
from calib.pose_change import moved_camera

CAMERA_PARAMETERS = (
    "f_px",
    "cx",
    "cy",
    "sx",
    "kappa1_px",
    "turn_x",
    "turn_y",
    "turn_z",
    "x",
    "y",
    "z",
)
"""The parameters of a camera's covariance: intrinsics (px, -, 1/px^2), turn about the
camera's own x, y, z axes (rad), optical centre's shift in the world (m)."""

N_CAMERA = len(CAMERA_PARAMETERS)
INTRINSICS = slice(0, 5)
POSE = slice(5, 11)
"""Where the intrinsics and the pose (turn, then shift) sit in the parameters."""

JACOBIAN_STEPS = np.array([1e-4, 1e-4, 1e-4, 1e-7, 1e-13, 1e-7, 1e-7, 1e-7, 1e-6, 1e-6, 1e-6])
"""Central-difference steps of each parameter, in its units."""


def perturbed_camera(camera: TsaiCamera, delta: ArrayLike) -> TsaiCamera:
    """``camera`` changed by (11,) ``delta`` in :data:`CAMERA_PARAMETERS`' terms."""
    d = np.asarray(delta, dtype=float).reshape(N_CAMERA)
    changed = camera.with_(
        f=camera.f + d[0],
        cx=camera.cx + d[1],
        cy=camera.cy + d[2],
        sx=camera.sx + d[3],
        kappa1=camera.kappa1 + d[4],
    )
    moved = moved_camera(changed, d[8:11], d[5:8])
    assert isinstance(moved, TsaiCamera)
    return moved


def camera_jacobian(camera: TsaiCamera, points_world: ArrayLike) -> NDArray[np.float64]:
    """(2N, 11) derivative of the pixels (u0, v0, u1, ...) of (N, 3) world points, m, with
    respect to :data:`CAMERA_PARAMETERS`, px per unit; NaN rows for points behind the
    camera."""
    p = np.asarray(points_world, dtype=float).reshape(-1, 3)

    def pixels(delta: NDArray[np.float64]) -> NDArray[np.float64]:
        return perturbed_camera(camera, delta).project_or_nan(p).ravel()

    return central_jacobian(pixels, np.zeros(N_CAMERA), JACOBIAN_STEPS)


def check_camera_covariance(cov: ArrayLike, what: str = "camera covariance") -> NDArray:
    """``cov`` as an (11, 11) symmetric matrix of finite numbers with a non-negative
    diagonal; ValueError naming ``what`` otherwise."""
    c = np.asarray(cov, dtype=float)
    if c.shape != (N_CAMERA, N_CAMERA):
        raise ValueError(f"{what}: expected an {N_CAMERA} x {N_CAMERA} matrix, got shape {c.shape}")
    if not np.all(np.isfinite(c)):
        raise ValueError(f"{what}: every entry must be a finite number")
    if not np.allclose(c, c.T, rtol=1e-6, atol=1e-12 * max(float(np.abs(c).max()), 1e-300)):
        raise ValueError(f"{what}: the matrix must be symmetric")
    if np.any(np.diag(c) < 0):
        raise ValueError(f"{what}: a variance (diagonal entry) is negative")
    return 0.5 * (c + c.T)
