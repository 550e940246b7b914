"""OpenCV's camera model, and the conversion of a Tsai camera into it.

OpenCV distorts *undistorted* normalised coordinates (k1, k2, p1, p2, k3[, k4, k5, k6]);
Tsai undistorts *distorted* ones. The two models are not exactly equivalent, so
:func:`tsai2opencv` fits OpenCV coefficients that reproduce a Tsai camera over the whole
image and reports the largest disagreement.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from calib.camera import TsaiCamera
from calib.checks import check_image_size, check_pixels, check_points_3d

DIST_NAMES = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")
_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-15)


@dataclass(frozen=True, eq=False)
class OpenCVCamera:
    """A camera in OpenCV's model.

    Attributes:
        camera_matrix: (3, 3) K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], px.
        dist_coeffs: (5,) or (8,) distortion coefficients (k1, k2, p1, p2, k3[, k4, k5, k6]).
        world2cam_r: (3, 3) rotation world -> camera. world2cam_t: (3,) translation, m.
        image_size: (width, height), px.
    """

    camera_matrix: NDArray[np.float64] = field(repr=False)
    dist_coeffs: NDArray[np.float64] = field(repr=False)
    world2cam_r: NDArray[np.float64] = field(default_factory=lambda: np.eye(3), repr=False)
    world2cam_t: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3), repr=False)
    image_size: tuple[int, int] = (320, 240)

    def __post_init__(self) -> None:
        k = np.asarray(self.camera_matrix, dtype=float).reshape(3, 3)
        d = np.asarray(self.dist_coeffs, dtype=float).ravel()
        if d.size not in (4, 5, 8):
            raise ValueError(f"dist_coeffs must have 4, 5 or 8 elements, got {d.size}")
        if d.size == 4:
            d = np.concatenate([d, [0.0]])
        if not (np.isfinite(k).all() and np.isfinite(d).all()):
            raise ValueError("camera_matrix and dist_coeffs must be finite")
        if k[0, 0] <= 0 or k[1, 1] <= 0:
            raise ValueError(f"fx and fy must be positive, got {k[0, 0]}, {k[1, 1]}")
        for name, value in (
            ("camera_matrix", k),
            ("dist_coeffs", d),
            ("world2cam_r", np.asarray(self.world2cam_r, dtype=float).reshape(3, 3)),
            ("world2cam_t", np.asarray(self.world2cam_t, dtype=float).reshape(3)),
        ):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "image_size", check_image_size(self.image_size))

    @property
    def position(self) -> NDArray[np.float64]:
        """(3,) optical centre in the world frame, m."""
        return -self.world2cam_r.T @ self.world2cam_t

    @property
    def fx(self) -> float:
        return float(self.camera_matrix[0, 0])

    @property
    def fy(self) -> float:
        return float(self.camera_matrix[1, 1])

    @property
    def cx(self) -> float:
        return float(self.camera_matrix[0, 2])

    @property
    def cy(self) -> float:
        return float(self.camera_matrix[1, 2])

    def project(self, points_world: ArrayLike) -> NDArray[np.float64]:
        """Project (N, 3) world points (m) to (N, 2) pixels with ``cv2.projectPoints``.

        Raises:
            ValueError: a point lies behind the camera.
        """
        p = check_points_3d(points_world)
        z = (p @ self.world2cam_r.T + self.world2cam_t)[:, 2]
        if (z <= 0).any():
            i = int(np.argmax(z <= 0))
            raise ValueError(
                f"{int((z <= 0).sum())} point(s) lie behind the camera, first in row {i}"
            )
        rvec = cv2.Rodrigues(self.world2cam_r)[0]
        uv, _ = cv2.projectPoints(
            p.reshape(-1, 1, 3), rvec, self.world2cam_t, self.camera_matrix, self.dist_coeffs
        )
        return uv.reshape(-1, 2).astype(float)

    def pixels_to_normalized(self, pixels: ArrayLike) -> NDArray[np.float64]:
        """(N, 2) pixels -> (N, 2) undistorted normalised coordinates (OpenCV's iteration)."""
        uv = check_pixels(pixels)
        xy = cv2.undistortPoints(
            uv.reshape(-1, 1, 2),
            self.camera_matrix,
            self.dist_coeffs,
            criteria=_UNDISTORT_CRITERIA,
        )
        return xy.reshape(-1, 2).astype(float)

    def unproject(self, pixels: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Lines of sight through (N, 2) pixels: (N, 3) origins and unit directions, world."""
        xy = self.pixels_to_normalized(pixels)
        rays = np.column_stack([xy, np.ones(len(xy))])
        rays /= np.linalg.norm(rays, axis=1, keepdims=True)
        dirs = rays @ self.world2cam_r
        return np.broadcast_to(self.position, dirs.shape).copy(), dirs


@dataclass(frozen=True)
class OpenCVConversion:
    """A Tsai camera converted to OpenCV's model.

    Attributes:
        camera: the OpenCV camera.
        max_error_px: largest disagreement between the two projections over the image, px.
    """

    camera: OpenCVCamera
    max_error_px: float


def image_grid(image_size: tuple[int, int], step: float = 4.0) -> NDArray[np.float64]:
    """(N, 2) pixels on a grid covering the whole image, corners and edges included."""
    w, h = image_size
    us = np.unique(np.concatenate([np.arange(-0.5, w - 0.5, step), [w - 0.5]]))
    vs = np.unique(np.concatenate([np.arange(-0.5, h - 0.5, step), [h - 0.5]]))
    uu, vv = np.meshgrid(us, vs)
    return np.column_stack([uu.ravel(), vv.ravel()])


def _opencv_radial(xy: NDArray[np.float64], d: NDArray[np.float64]) -> NDArray[np.float64]:
    """OpenCV's radial distortion (no tangential terms) of normalised points."""
    r2 = np.sum(xy * xy, axis=1, keepdims=True)
    num = 1 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]))
    den = 1 + r2 * (d[5] + r2 * (d[6] + r2 * d[7])) if d.size == 8 else 1.0
    return xy * num / den


def tsai2opencv(camera: TsaiCamera, *, tolerance_px: float = 0.01) -> OpenCVConversion:
    """Fit OpenCV coefficients that reproduce a Tsai camera over the whole image.

    K takes fx = sx f, fy = f and the same image centre. The radial coefficients k1, k2, k3
    are fitted by linear least squares in pixels on a grid covering the image (Tsai's
    undistortion of that grid is exact); if the largest error still exceeds
    ``tolerance_px``, the rational model (k4, k5, k6) is fitted as well. The agreement is
    then measured with ``cv2.projectPoints`` itself.

    Args:
        camera: the Tsai camera.
        tolerance_px: accept the polynomial fit below this largest error, px.

    Returns:
        The OpenCV camera (same pose) and the largest and RMS disagreement, px.
    """
    f, sx = camera.f, camera.sx
    grid = image_grid(camera.image_size)
    xy_u = camera.pixels_to_normalized(grid)  # exact inverse of Tsai's distortion
    xy_d = np.column_stack([(grid[:, 0] - camera.cx) / (sx * f), (grid[:, 1] - camera.cy) / f])
    scale = np.array([sx * f, f])
    r2 = np.sum(xy_u * xy_u, axis=1)
    a = np.concatenate(
        [(xy_u[:, i : i + 1] * np.column_stack([r2, r2**2, r2**3])) * scale[i] for i in (0, 1)]
    )
    b = np.concatenate([(xy_d[:, i] - xy_u[:, i]) * scale[i] for i in (0, 1)])
    (k1, k2, k3), *_ = np.linalg.lstsq(a, b, rcond=None)
    d = np.array([k1, k2, 0.0, 0.0, k3])

    def pixel_error(dd: NDArray[np.float64]) -> NDArray[np.float64]:
        return ((_opencv_radial(xy_u, dd) - xy_d) * scale).ravel()

    if np.abs(pixel_error(d)).max() > tolerance_px:
        d8 = np.concatenate([d, [0.0, 0.0, 0.0]])
        free = [0, 1, 4, 5, 6, 7]

        def res8(p: NDArray[np.float64]) -> NDArray[np.float64]:
            dd = d8.copy()
            dd[free] = p
            return pixel_error(dd)

        sol = least_squares(res8, d8[free], method="lm", xtol=1e-15, ftol=1e-15)
        d8[free] = sol.x
        d = d8
    k = np.array([[sx * f, 0.0, camera.cx], [0.0, f, camera.cy], [0.0, 0.0, 1.0]])
    cv_cam = OpenCVCamera(k, d, camera.world2cam_r, camera.world2cam_t, camera.image_size)
    # Measure with OpenCV itself: rays through the grid, projected back by cv2.projectPoints.
    origins, dirs = camera.unproject(grid)
    err = np.linalg.norm(cv_cam.project(origins + 5.0 * dirs) - grid, axis=1)
    return OpenCVConversion(cv_cam, float(err.max()))
