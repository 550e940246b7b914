"""The parameter vector of Tsai's calibration, shared by its two optimisers.

Both :func:`calib.tsai.calibrate_tsai` (one camera) and :func:`calib.tsai_lm.calibrate_tsai_batch`
(T cameras) optimise 11 internal parameters

    q = [f, cx, cy, sx, kappa1 * kscale, rotation vector (3), optical centre C (3)]

(px, px, px, -, -, rad, m), kscale the squared half-diagonal of the image
(:func:`kappa_scale`), and report them as ``TSAI_PARAMETERS`` (kappa1 in 1/px^2, the
rotation as Tsai's angles).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from calib.camera import TsaiCamera, TsaiCameras
from calib.camera_jacobian import project_tsai_jacobian
from calib.rotation import (
    EULER_SEQ,
    matrix2euler,
    right_jacobian_batch,
    rotvec2matrix,
    rotvec2matrix_batch,
)

TSAI_PARAMETERS = ("f_px", "cx", "cy", "sx", "kappa1_px", "rx", "ry", "rz", "x", "y", "z")
N_TSAI = len(TSAI_PARAMETERS)
INVALID_PX = 1e6  # the pixel given to a point that does not project
ROTATION_STEP = 1e-6  # rad: central-difference step of Euler angles against the rotvec


def kappa_scale(image_size: tuple[int, int]) -> float:
    """Squared half-diagonal of the image, px^2: kappa1 is optimised as kappa1 * this."""
    w, h = image_size
    return (w / 2.0) ** 2 + (h / 2.0) ** 2


def pack(camera: TsaiCamera | TsaiCameras) -> NDArray[np.float64]:
    """One camera -> (11,) internal parameters q; T cameras -> (T, 11)."""
    k = camera.kappa1 * kappa_scale(camera.image_size)
    rv = Rotation.from_matrix(camera.world2cam_r).as_rotvec()
    intrinsics = np.stack([camera.f, camera.cx, camera.cy, camera.sx, k], axis=-1)
    return np.concatenate([intrinsics, rv, camera.position], axis=-1)


def unpack(q: NDArray[np.float64], image_size: tuple[int, int]) -> TsaiCamera:
    """(11,) internal parameters -> the camera (:func:`pack`'s inverse)."""
    r = rotvec2matrix(q[5:8])
    k = q[4] / kappa_scale(image_size)
    return TsaiCamera(q[0], q[1], q[2], k, q[3], r, -r @ q[8:11], image_size)


def reported(q: NDArray[np.float64], kscale: float) -> NDArray[np.float64]:
    """(11,) internal parameters -> reported [f, cx, cy, sx, kappa1, rx, ry, rz, x, y, z]."""
    euler = matrix2euler(rotvec2matrix(q[5:8]))
    return np.concatenate([q[:4], [q[4] / kscale], euler, q[8:11]])


def _euler(rotvecs: NDArray[np.float64]) -> NDArray[np.float64]:
    """(T, 3) rotation vectors -> (T, 3) Tsai angles (rx, ry, rz), rad."""
    return Rotation.from_matrix(rotvec2matrix_batch(rotvecs)).as_euler(EULER_SEQ)


def reported_batch(q: NDArray[np.float64], kscale: float) -> NDArray[np.float64]:
    """(T, 11) internal parameters -> (T, 11) reported ones (as :func:`reported`)."""
    return np.concatenate([q[:, :4], q[:, 4:5] / kscale, _euler(q[:, 5:8]), q[:, 8:11]], axis=1)


def reporting_jacobian(q: NDArray[np.float64], kscale: float) -> NDArray[np.float64]:
    """(T, 11, 11) derivative of the reported parameters against the internal ones at
    (T, 11) ``q``.

    The identity but for kappa1 (1 / kscale) and the angles, whose derivative against the
    rotation vector is taken by central differences as ``calib.tsai`` does.
    """
    n_t = len(q)
    jac = np.broadcast_to(np.eye(N_TSAI), (n_t, N_TSAI, N_TSAI)).copy()
    jac[:, 4, 4] = 1.0 / kscale
    for i in range(3):
        step = np.zeros(3)
        step[i] = ROTATION_STEP
        diff = _euler(q[:, 5:8] + step) - _euler(q[:, 5:8] - step)
        jac[:, 5:8, 5 + i] = np.angle(np.exp(1j * diff)) / (2.0 * ROTATION_STEP)
    return jac


def residuals_and_jacobian(
    q: NDArray[np.float64],
    points: NDArray[np.float64],
    pixels: NDArray[np.float64],
    kscale: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Reprojection residuals (T, 2N), px, and their Jacobian (T, 2N, 11) at q (T, 11),
    for (T, N, 3) points and (T, N, 2) pixels.

    A point that does not project gets the pixel ``INVALID_PX``, and the NaN in its rows of
    the Jacobian become 0.
    """
    rot = rotvec2matrix_batch(q[:, 5:8])
    uv, jac = project_tsai_jacobian(
        points,
        q[:, 0],
        q[:, 1],
        q[:, 2],
        q[:, 3],
        q[:, 4] / kscale,
        rot,
        q[:, 8:11],
        right_jacobian_batch(q[:, 5:8]),
    )
    n_t = len(q)
    uv = uv.reshape(n_t, -1)
    jac = jac.reshape(n_t, -1, N_TSAI)
    jac[:, :, 4] /= kscale
    bad = ~np.isfinite(uv)
    if bad.any():
        uv = np.where(bad, INVALID_PX, uv)
        jac[bad] = np.nan_to_num(jac[bad], nan=0.0)
    return uv - pixels.reshape(n_t, -1), jac
