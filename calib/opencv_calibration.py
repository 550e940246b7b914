"""Calibration in OpenCV's model with ``cv2.calibrateCamera``, started from Tsai's stages.

For lenses that Tsai's single radial coefficient does not fit, a user can pick this model:
k1 and k2 free, and optionally the tangential coefficients p1, p2 and k3. The unstable
coefficients are fixed at zero by default. The start (focal length, image centre, aspect)
comes from Tsai's closed-form stages, so non-planar LED data need no calibration pattern.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from calib.checks import (
    check_correspondences,
    check_image_size,
    check_min_points,
    check_pixels_in_image,
    check_spread,
)
from calib.covariance import central_jacobian
from calib.duplicates import drop_duplicates
from calib.opencv_camera import DIST_NAMES, OpenCVCamera
from calib.result import CalibrationResult, result_from_fit
from calib.rotation import matrix2euler, matrix2rotvec, rotvec2matrix
from calib.tsai_linear import LINEAR_MIN_POINTS, tsai_initial_estimate


def _free_dist(tangential: bool, k3: bool) -> list[int]:
    """Indices into (k1, k2, p1, p2, k3) of the coefficients that are estimated."""
    free = [0, 1]
    if tangential:
        free += [2, 3]
    if k3:
        free.append(4)
    return free


def calibrate_opencv(
    points_3d: ArrayLike,
    pixels: ArrayLike,
    image_size: tuple[int, int],
    *,
    tangential: bool = False,
    k3: bool = False,
    keep_duplicates: bool = False,
) -> CalibrationResult:
    """Calibrate in OpenCV's model (fx, fy, cx, cy, k1, k2[, p1, p2][, k3], pose).

    Args:
        points_3d: (N, 3) non-coplanar world points, m.
        pixels: (N, 2) observed pixels.
        image_size: (width, height), px.
        tangential: also estimate p1 and p2 (fixed at 0 by default).
        k3: also estimate k3 (fixed at 0 by default: it is unstable with few points).
        keep_duplicates: fit exact duplicate rows as independent measurements (by default
            they are merged and noted; see :mod:`calib.duplicates`).

    Returns:
        The OpenCVCamera and the parameters fx, fy, cx, cy, the free distortion
        coefficients, rx, ry, rz (rad, about the world axes) and x, y, z (m) with their
        covariance.
    """
    p3, uv = check_correspondences(points_3d, pixels)
    size = check_image_size(image_size)
    p3, uv, duplicates = drop_duplicates(p3, uv, keep_duplicates)
    free = _free_dist(tangential, k3)
    n_par = 4 + len(free) + 6
    check_min_points(
        len(p3),
        max(LINEAR_MIN_POINTS, (n_par + 2) // 2),
        f"OpenCV-model calibration ({n_par} parameters, started from Tsai's linear stage)",
    )
    check_pixels_in_image(uv, size)
    check_spread(p3, need_3d=True, what="OpenCV-model calibration from non-coplanar points")

    init = tsai_initial_estimate(p3, uv, size, check=False)
    k0 = np.array([[init.sx * init.f, 0, init.cx], [0, init.f, init.cy], [0, 0, 1.0]])
    flags = cv2.CALIB_USE_INTRINSIC_GUESS
    if not tangential:
        flags |= cv2.CALIB_ZERO_TANGENT_DIST
    if not k3:
        flags |= cv2.CALIB_FIX_K3
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-15)
    _, k, d, rvecs, tvecs, *_ = cv2.calibrateCameraExtended(
        [p3.astype(np.float32)],
        [uv.astype(np.float32)],
        size,
        k0,
        np.zeros(5),
        flags=flags,
        criteria=criteria,
    )
    r = cv2.Rodrigues(rvecs[0])[0]
    t = tvecs[0].ravel()

    # Polish in double precision (OpenCV's solver works on float32 points) and get the
    # covariance from the Jacobian of the reprojection residuals.
    d5 = np.asarray(d, dtype=float).ravel()[:5]

    def camera_of(q: NDArray[np.float64]) -> OpenCVCamera:
        dd = np.zeros(5)
        dd[free] = q[4 : 4 + len(free)]
        kk = np.array([[q[0], 0, q[2]], [0, q[1], q[3]], [0, 0, 1.0]])
        rr = rotvec2matrix(q[-6:-3])
        return OpenCVCamera(kk, dd, rr, -rr @ q[-3:], size)

    uv_flat = uv.ravel()

    def residual(q: NDArray[np.float64]) -> NDArray[np.float64]:
        return camera_of(q).project(p3).ravel() - uv_flat

    q0 = np.concatenate(
        [[k[0, 0], k[1, 1], k[0, 2], k[1, 2]], d5[free], matrix2rotvec(r), -r.T @ t]
    )
    steps = np.concatenate(
        [[1e-3, 1e-3, 1e-3, 1e-3], np.full(len(free), 1e-6), [1e-6] * 3, [1e-5] * 3]
    )

    sol = least_squares(
        residual,
        q0,
        jac=lambda q: central_jacobian(residual, q, steps),
        method="lm",
        xtol=1e-15,
        ftol=1e-15,
        gtol=1e-15,
    )
    q = sol.x
    cam = camera_of(q)

    def reported(x: NDArray[np.float64]) -> NDArray[np.float64]:
        euler = matrix2euler(rotvec2matrix(x[-6:-3]))
        return np.concatenate([x[:-6], euler, x[-3:]])

    names = (
        "fx",
        "fy",
        "cx",
        "cy",
        *(DIST_NAMES[i] for i in free),
        "rx",
        "ry",
        "rz",
        "x",
        "y",
        "z",
    )
    j = central_jacobian(residual, q, steps)
    return result_from_fit(
        "opencv",
        cam,
        names,
        q,
        j,
        residual(q),
        reported,
        steps,
        p3,
        uv,
        duplicates=duplicates,
        duplicates_kept=keep_duplicates,
    )
