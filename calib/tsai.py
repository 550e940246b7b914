"""Tsai's non-coplanar calibration with full optimisation of all 11 parameters.

:func:`calibrate_tsai` runs the closed-form stages of :mod:`calib.tsai_linear`, then refines
f, cx, cy, sx, kappa1, the rotation and the camera position together with
``scipy.optimize.least_squares``, minimising the reprojection error in pixels, and reports
the parameter covariance from the final Jacobian scaled by the residual variance.

:func:`calibrate_exterior` estimates only the pose of a camera whose intrinsics are known,
for re-calibrating a camera that was moved.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from calib.camera import TsaiCamera, project_tsai
from calib.camera_jacobian import project_tsai_jacobian
from calib.checks import (
    check_correspondences,
    check_image_size,
    check_min_points,
    check_pixels_in_image,
    check_points_3d,
    check_spread,
)
from calib.covariance import (
    central_jacobian,
    propagate_covariance,
    unit_covariance,
)
from calib.duplicates import drop_duplicates
from calib.result import CalibrationResult, result_from_fit
from calib.rotation import matrix2euler, matrix2rotvec, right_jacobian, rotvec2matrix
from calib.tsai_linear import LINEAR_MIN_POINTS, tsai_initial_estimate
from calib.tsai_parameters import (
    N_TSAI,
    TSAI_PARAMETERS,
    kappa_scale,
    pack,
    reported,
    unpack,
)

EXTERIOR_PARAMETERS = ("rx", "ry", "rz", "x", "y", "z")
FULL_MIN_POINTS = 6  # 11 parameters need at least 12 residuals


def _project_q(
    q: NDArray[np.float64], p3: NDArray[np.float64], kscale: float
) -> NDArray[np.float64]:
    r = rotvec2matrix(q[5:8])
    return project_tsai(p3, q[0], q[1], q[2], q[3], q[4] / kscale, r, -r @ q[8:11])


def _steps(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Finite-difference steps for the internal parameters (px, -, rad, m)."""
    return np.array([1e-4 * abs(q[0]), 1e-3, 1e-3, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-5, 1e-5, 1e-5])


def _pixel_jacobian(
    p3: NDArray[np.float64], image_size: tuple[int, int]
) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """Internal parameters -> (2N, 11) analytic Jacobian of the projected pixels."""
    kscale = kappa_scale(image_size)

    def jac_of(q: NDArray[np.float64]) -> NDArray[np.float64]:
        r = rotvec2matrix(q[5:8])
        _, j = project_tsai_jacobian(
            p3, q[0], q[1], q[2], q[3], q[4] / kscale, r, q[8:11], right_jacobian(q[5:8])
        )
        j[:, :, 4] /= kscale
        return np.nan_to_num(j.reshape(-1, N_TSAI), nan=0.0)

    return jac_of


def _pixel_function(
    p3: NDArray[np.float64], image_size: tuple[int, int]
) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """Internal parameters -> (2N,) projected pixels of the points (NaN-free: 1e6 if invalid)."""
    kscale = kappa_scale(image_size)

    def pixels_of(q: NDArray[np.float64]) -> NDArray[np.float64]:
        uv = _project_q(q, p3, kscale).ravel()
        return np.where(np.isfinite(uv), uv, 1e6)

    return pixels_of


def _reported_covariance(
    cov_q: NDArray[np.float64], q: NDArray[np.float64], kscale: float
) -> NDArray[np.float64]:
    """Covariance of the internal parameters -> covariance of the reported ones."""
    angle_mask = np.zeros(N_TSAI, dtype=bool)
    angle_mask[5:8] = True
    return propagate_covariance(cov_q, lambda x: reported(x, kscale), q, _steps(q), angle_mask)


def predicted_covariance(
    camera: TsaiCamera, points_3d: ArrayLike, sigma_px: float
) -> NDArray[np.float64]:
    """Covariance of the 11 Tsai parameters that a calibration on these points would have.

    The Cramer-Rao bound for independent Gaussian pixel noise of ``sigma_px`` on both
    coordinates, evaluated at ``camera`` (the truth, or a planned camera): use it to judge a
    planned set of LED positions before measuring them.

    Args:
        camera: the (true or planned) camera.
        points_3d: (N, 3) world points, m.
        sigma_px: standard deviation of the pixel noise, px.

    Returns:
        (11, 11) covariance in the order of ``TSAI_PARAMETERS`` (SI units).
    """
    p3 = check_points_3d(points_3d)
    q = pack(camera)
    j = _pixel_jacobian(p3, camera.image_size)(q)
    cov_q = sigma_px**2 * unit_covariance(j)
    return _reported_covariance(cov_q, q, kappa_scale(camera.image_size))


def pixel_jacobian(camera: TsaiCamera, points_3d: ArrayLike) -> NDArray[np.float64]:
    """Derivatives of the projected pixels with respect to Tsai's internal parameters.

    The parameters are those the calibration optimises: f, cx, cy, sx, kappa1 times the
    squared half-diagonal of the image, the world-to-camera rotation vector (3) and the
    optical centre in the world (3, m, the last three). The derivative of the pixels with
    respect to a world point is minus the last three columns.

    Args:
        camera: the (true or planned) camera.
        points_3d: (N, 3) world points, m.

    Returns:
        (N, 2, 11) Jacobian, px per parameter (0 for points behind the camera).
    """
    p3 = np.asarray(points_3d, dtype=float).reshape(-1, 3)
    return _pixel_jacobian(p3, camera.image_size)(pack(camera)).reshape(len(p3), 2, N_TSAI)


def tsai_vector(camera: TsaiCamera) -> NDArray[np.float64]:
    """The (11,) parameter vector a calibration optimises (see :func:`pixel_jacobian`):
    f, cx, cy, sx (px, px, px, -), kappa1 times the squared half-diagonal of the image (-),
    the world-to-camera rotation vector (rad) and the optical centre in the world (m)."""
    return pack(camera)


def tsai_from_vector(q: ArrayLike, image_size: tuple[int, int]) -> TsaiCamera:
    """The camera of an (11,) parameter vector (:func:`tsai_vector`'s inverse)."""
    return unpack(np.asarray(q, dtype=float), check_image_size(image_size))


def tsai_pixels_and_jacobian(
    q: ArrayLike, points_3d: ArrayLike, image_size: tuple[int, int]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Projected pixels and their derivatives with respect to the parameter vector.

    Args:
        q: (11,) parameters (:func:`tsai_vector`). points_3d: (N, 3) world points, m.
        image_size: (width, height), px.

    Returns:
        (N, 2) pixels (NaN behind the camera) and the (N, 2, 11) Jacobian, px per
        parameter. The derivative with respect to a world point is minus the last three
        columns.
    """
    x = np.asarray(q, dtype=float)
    p3 = np.asarray(points_3d, dtype=float).reshape(-1, 3)
    kscale = kappa_scale(image_size)
    jac = _pixel_jacobian(p3, image_size)(x).reshape(len(p3), 2, N_TSAI)
    return _project_q(x, p3, kscale), jac


def tsai_reported(
    q: ArrayLike, covariance: ArrayLike, image_size: tuple[int, int]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """An (11,) parameter vector and its (11, 11) covariance in the reported parameters
    (``TSAI_PARAMETERS``: rotation as Euler angles, kappa1 in 1/px^2), as a calibration
    reports them."""
    x = np.asarray(q, dtype=float)
    kscale = kappa_scale(image_size)
    cov = _reported_covariance(np.asarray(covariance, dtype=float), x, kscale)
    return reported(x, kscale), cov


def calibrate_tsai(
    points_3d: ArrayLike,
    pixels: ArrayLike,
    image_size: tuple[int, int],
    *,
    centre: tuple[float, float] | None = None,
    keep_duplicates: bool = False,
) -> CalibrationResult:
    """Calibrate a camera with Tsai's non-coplanar method and full optimisation.

    Needs at least 7 non-coplanar points: the linear radial-alignment stage has 7
    unknowns. The full optimisation of the 11 parameters then needs 12 residuals (6 points),
    and meaningful standard deviations need a good margin beyond that (a note is attached
    when the fit has fewer than 10 degrees of freedom). Rows that repeat an earlier row
    exactly are merged and noted (see :mod:`calib.duplicates`).

    Args:
        points_3d: (N, 3) world points, m.
        pixels: (N, 2) observed pixels (OpenCV convention).
        image_size: (width, height), px.
        centre: the image centre to assume in the linear stage; default the image's centre.
        keep_duplicates: fit exact duplicate rows as independent measurements.

    Returns:
        The calibrated camera, the 11 parameters (f_px, cx, cy, sx, kappa1_px, rx, ry, rz in
        rad, x, y, z of the optical centre in m) with their covariance, and the Table III
        metrics on the calibration data.
    """
    p3, uv = check_correspondences(points_3d, pixels)
    size = check_image_size(image_size)
    p3, uv, duplicates = drop_duplicates(p3, uv, keep_duplicates)
    check_min_points(
        len(p3),
        LINEAR_MIN_POINTS,
        "Tsai calibration (its linear radial-alignment stage has 7 unknowns; the full "
        f"optimisation of {N_TSAI} parameters needs at least {FULL_MIN_POINTS})",
    )
    check_pixels_in_image(uv, size)
    spread = check_spread(p3, need_3d=True, what="Tsai's non-coplanar calibration")

    init = tsai_initial_estimate(p3, uv, size, centre, check=False)
    cam0 = TsaiCamera(
        init.f, init.cx, init.cy, init.kappa1, init.sx, init.world2cam_r, init.world2cam_t, size
    )
    behind = (cam0.to_camera_frame(p3)[:, 2] <= 0).sum()
    if behind:
        raise ValueError(
            f"{int(behind)} of {len(p3)} points lie behind the camera found by the linear "
            "stage: either the points and pixels do not correspond, or the points are too "
            f"close to coplanar for their noise (point-cloud condition number {spread:.3g}, "
            f"linear-stage condition number {init.condition:.3g})"
        )
    kscale = kappa_scale(size)
    pixels_of = _pixel_function(p3, size)
    uv_flat = uv.ravel()

    def residual(q: NDArray[np.float64]) -> NDArray[np.float64]:
        return pixels_of(q) - uv_flat

    jac = _pixel_jacobian(p3, size)

    q0 = pack(cam0)
    sol = least_squares(
        residual, q0, jac=jac, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=200
    )
    q = sol.x
    cam = unpack(q, size)
    if (cam.to_camera_frame(p3)[:, 2] <= 0).any():
        raise ValueError("the optimisation put points behind the camera; the data are inconsistent")

    return result_from_fit(
        "tsai",
        cam,
        TSAI_PARAMETERS,
        q,
        jac(q),
        residual(q),
        lambda x: reported(x, kscale),
        _steps(q),
        p3,
        uv,
        cam0,
        duplicates=duplicates,
        duplicates_kept=keep_duplicates,
    )


def calibrate_exterior(
    points_3d: ArrayLike,
    pixels: ArrayLike,
    intrinsics: TsaiCamera,
    *,
    keep_duplicates: bool = False,
) -> CalibrationResult:
    """Estimate the pose of a camera whose intrinsics are known (a camera that was moved).

    The pose is started from OpenCV's PnP on the exactly undistorted pixels and refined by
    least squares on the reprojection error in pixels. Coplanar points are allowed. Rows
    that repeat an earlier row exactly are merged and noted (see :mod:`calib.duplicates`).

    Args:
        points_3d: (N, 3) world points, N >= 4, m.
        pixels: (N, 2) observed pixels.
        intrinsics: a TsaiCamera whose f, cx, cy, sx, kappa1 and image size are used; its
            pose is ignored.
        keep_duplicates: fit exact duplicate rows as independent measurements.

    Returns:
        The camera with the new pose; parameters rx, ry, rz (rad) and x, y, z (m) with their
        covariance.
    """
    import cv2

    p3, uv = check_correspondences(points_3d, pixels)
    p3, uv, duplicates = drop_duplicates(p3, uv, keep_duplicates)
    check_min_points(len(p3), 4, "exterior calibration (6 pose parameters, PnP)")
    check_pixels_in_image(uv, intrinsics.image_size)
    check_spread(p3, need_3d=False, what="exterior calibration")
    xy = intrinsics.pixels_to_normalized(uv)
    ok, rvec, tvec = cv2.solvePnP(
        p3.reshape(-1, 1, 3), xy.reshape(-1, 1, 2), np.eye(3), None, flags=cv2.SOLVEPNP_SQPNP
    )
    if not ok:
        raise ValueError("PnP found no pose for these points; check the correspondences")
    r0 = cv2.Rodrigues(rvec)[0]
    q0 = np.concatenate([matrix2rotvec(r0), -r0.T @ tvec.ravel()])
    f, cx, cy, sx, k1 = intrinsics.f, intrinsics.cx, intrinsics.cy, intrinsics.sx, intrinsics.kappa1
    uv_flat = uv.ravel()

    def residual(q: NDArray[np.float64]) -> NDArray[np.float64]:
        r = rotvec2matrix(q[:3])
        res = project_tsai(p3, f, cx, cy, sx, k1, r, -r @ q[3:]).ravel() - uv_flat
        return np.where(np.isfinite(res), res, 1e6)

    steps = np.array([1e-6, 1e-6, 1e-6, 1e-5, 1e-5, 1e-5])

    def jac(q: NDArray[np.float64]) -> NDArray[np.float64]:
        return central_jacobian(residual, q, steps)

    sol = least_squares(residual, q0, jac=jac, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    q = sol.x
    r = rotvec2matrix(q[:3])
    cam = intrinsics.with_(world2cam_r=r, world2cam_t=-r @ q[3:])

    def reported(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.concatenate([matrix2euler(rotvec2matrix(x[:3])), x[3:]])

    return result_from_fit(
        "tsai-exterior",
        cam,
        EXTERIOR_PARAMETERS,
        q,
        jac(q),
        residual(q),
        reported,
        steps,
        p3,
        uv,
        duplicates=duplicates,
        duplicates_kept=keep_duplicates,
    )
