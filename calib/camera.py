"""Tsai's camera model: pinhole with first-order radial distortion and a horizontal scale.

A world point X (m) maps to a pixel (u, v) by

    [x_c, y_c, z_c] = R @ X + t                   (R, t: world-to-camera, OpenCV frame)
    (x_u, y_u) = f * (x_c, y_c) / z_c             (px, undistorted)
    (x_u, y_u) = (x_d, y_d) * (1 + kappa1 r_d^2)  (Tsai's distortion, solved for x_d, y_d)
    u = sx * x_d + cx,  v = y_d + cy              (px, OpenCV pixel convention)

Pixel (0, 0) is the centre of the top-left pixel. The camera frame is OpenCV's: x right,
y down, z forward.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.checks import check_image_size, check_pixels, check_points_3d
from calib.distortion import distort, undistort
from calib.rotation import euler2matrix, look_at_world2cam, matrix2euler


def project_tsai(
    points_world: NDArray[np.float64],
    f: float,
    cx: float,
    cy: float,
    sx: float,
    kappa1: float,
    world2cam_r: NDArray[np.float64],
    world2cam_t: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Project world points with Tsai's model, without input checks.

    Args:
        points_world: (N, 3) points, m.
        f: focal length, px. cx, cy: image centre, px. sx: horizontal scale factor.
        kappa1: radial distortion, 1/px^2.
        world2cam_r: (3, 3) rotation. world2cam_t: (3,) translation, m.

    Returns:
        (N, 2) pixels. Points with z_c <= 0 or beyond the distortion fold give NaN.
    """
    pc = points_world @ world2cam_r.T + world2cam_t
    z = pc[:, 2:3]
    with np.errstate(divide="ignore", invalid="ignore"):
        xy_u = np.where(z > 0, f * pc[:, :2] / z, np.nan)
    xy_d = distort(xy_u, kappa1)
    return np.column_stack([sx * xy_d[:, 0] + cx, xy_d[:, 1] + cy])


@dataclass(frozen=True, eq=False)
class TsaiCamera:
    """A calibrated camera in Tsai's model. All lengths in metres, image quantities in px.

    Attributes:
        f: focal length / pixel height, px (the paper's "focus length / pixel size").
        cx, cy: image centre (principal point), px, OpenCV convention.
        kappa1: first-order radial distortion, 1/px^2, Tsai's direction
            (undistorted = distorted * (1 + kappa1 r_d^2)).
        sx: horizontal scale factor (pixel aspect uncertainty), dimensionless.
        world2cam_r: (3, 3) rotation from world to camera frame.
        world2cam_t: (3,) translation from world to camera frame, m.
        image_size: (width, height), px.
    """

    f: float
    cx: float
    cy: float
    kappa1: float
    sx: float
    world2cam_r: NDArray[np.float64] = field(repr=False)
    world2cam_t: NDArray[np.float64] = field(repr=False)
    image_size: tuple[int, int] = (320, 240)

    def __post_init__(self) -> None:
        r = np.asarray(self.world2cam_r, dtype=float).reshape(3, 3)
        t = np.asarray(self.world2cam_t, dtype=float).reshape(3)
        if not np.allclose(r @ r.T, np.eye(3), atol=1e-9) or np.linalg.det(r) < 0:
            raise ValueError("world2cam_r must be a proper rotation matrix")
        for name in ("f", "cx", "cy", "kappa1", "sx"):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"camera parameter {name} must be finite")
        if self.f <= 0 or self.sx <= 0:
            raise ValueError(f"f and sx must be positive, got f={self.f}, sx={self.sx}")
        r.setflags(write=False)
        t.setflags(write=False)
        object.__setattr__(self, "world2cam_r", r)
        object.__setattr__(self, "world2cam_t", t)
        object.__setattr__(self, "image_size", check_image_size(self.image_size))

    # -- construction -------------------------------------------------------------------
    @classmethod
    def from_pose(
        cls,
        *,
        f: float,
        cx: float,
        cy: float,
        kappa1: float = 0.0,
        sx: float = 1.0,
        position: ArrayLike,
        rotation_rad: ArrayLike | None = None,
        view_direction: ArrayLike | None = None,
        image_size: tuple[int, int] = (320, 240),
    ) -> TsaiCamera:
        """Build a camera from its optical centre in the world and its orientation.

        Give the orientation either as Tsai's angles ``rotation_rad`` (rx, ry, rz about the
        world axes, world-to-camera) or as a ``view_direction`` (image up = world up).
        """
        if (rotation_rad is None) == (view_direction is None):
            raise ValueError("give exactly one of rotation_rad and view_direction")
        if rotation_rad is not None:
            r = euler2matrix(rotation_rad)
        else:
            r = look_at_world2cam(view_direction)
        c = np.asarray(position, dtype=float).reshape(3)
        return cls(f, cx, cy, kappa1, sx, r, -r @ c, image_size)

    def with_(self, **changes: object) -> TsaiCamera:
        """A copy with some fields changed."""
        return replace(self, **changes)

    # -- derived quantities -------------------------------------------------------------
    @property
    def position(self) -> NDArray[np.float64]:
        """(3,) optical centre in the world frame, m."""
        return -self.world2cam_r.T @ self.world2cam_t

    @property
    def rotation_rad(self) -> NDArray[np.float64]:
        """(3,) Tsai angles (rx, ry, rz) about the world axes, rad; R = Rz Ry Rx."""
        return matrix2euler(self.world2cam_r)

    @property
    def optical_axis(self) -> NDArray[np.float64]:
        """(3,) unit direction of the optical axis in the world frame."""
        return self.world2cam_r[2].copy()

    def to_camera_frame(self, points_world: ArrayLike) -> NDArray[np.float64]:
        """(N, 3) world points -> (N, 3) points in the camera frame, m."""
        p = check_points_3d(points_world)
        return p @ self.world2cam_r.T + self.world2cam_t

    # -- projection ---------------------------------------------------------------------
    def project_or_nan(self, points_world: ArrayLike) -> NDArray[np.float64]:
        """Project (N, 3) world points (m) to (N, 2) distorted pixels, without raising: a
        row is NaN where its point lies behind the camera (z_c <= 0) or beyond the fold of
        a negative kappa1. Every other row is what :meth:`project` gives (the same
        computation, for any number of points at once)."""
        return self._project(check_points_3d(points_world))

    def project(self, points_world: ArrayLike) -> NDArray[np.float64]:
        """Project (N, 3) world points (m) to (N, 2) distorted pixels.

        Raises:
            ValueError: a point lies behind the camera (z_c <= 0) or beyond the fold of a
                negative kappa1, with the number of such points and the first row.
        """
        p = check_points_3d(points_world)
        z = (p @ self.world2cam_r.T + self.world2cam_t)[:, 2]
        behind = z <= 0
        if behind.any():
            i = int(np.argmax(behind))
            raise ValueError(
                f"{int(behind.sum())} point(s) lie behind the camera, first in row {i} "
                f"(z_c = {z[i]:.4g} m)"
            )
        uv = self._project(p)
        fold = np.isnan(uv[:, 0])
        if fold.any():
            i = int(np.argmax(fold))
            raise ValueError(
                f"{int(fold.sum())} point(s) lie outside the field covered by the lens "
                f"(beyond the fold of kappa1 = {self.kappa1:.3g}), first in row {i}"
            )
        return uv

    def _project(self, points_world: NDArray[np.float64]) -> NDArray[np.float64]:
        """(N, 3) checked world points -> (N, 2) pixels, NaN where not projectable."""
        return project_tsai(points_world, *self._intrinsics(), self.world2cam_r, self.world2cam_t)

    def pixels_to_normalized(self, pixels: ArrayLike) -> NDArray[np.float64]:
        """(N, 2) distorted pixels -> (N, 2) undistorted normalised coordinates x_c/z_c."""
        uv = check_pixels(pixels)
        xy_d = np.column_stack([(uv[:, 0] - self.cx) / self.sx, uv[:, 1] - self.cy])
        return undistort(xy_d, self.kappa1) / self.f

    def unproject(self, pixels: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Lines of sight through (N, 2) pixels.

        Returns:
            origins: (N, 3) the optical centre in the world frame, m (same for every row).
            directions: (N, 3) unit directions in the world frame.
        """
        xy = self.pixels_to_normalized(pixels)
        rays_c = np.column_stack([xy, np.ones(len(xy))])
        rays_c /= np.linalg.norm(rays_c, axis=1, keepdims=True)
        directions = rays_c @ self.world2cam_r
        origins = np.broadcast_to(self.position, directions.shape).copy()
        return origins, directions

    def in_image(self, pixels: ArrayLike) -> NDArray[np.bool_]:
        """(N,) True where a pixel lies inside the image (OpenCV convention)."""
        uv = np.asarray(pixels, dtype=float).reshape(-1, 2)
        w, h = self.image_size
        ok = np.isfinite(uv).all(axis=1)
        return (
            ok
            & (uv[:, 0] >= -0.5)
            & (uv[:, 0] <= w - 0.5)
            & (uv[:, 1] >= -0.5)
            & (uv[:, 1] <= h - 0.5)
        )

    def _intrinsics(self) -> tuple[float, float, float, float, float]:
        return self.f, self.cx, self.cy, self.sx, self.kappa1

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, TsaiCamera):
            return NotImplemented
        return (
            self._intrinsics() == other._intrinsics()
            and self.image_size == other.image_size
            and np.array_equal(self.world2cam_r, other.world2cam_r)
            and np.array_equal(self.world2cam_t, other.world2cam_t)
        )

    __hash__ = None  # type: ignore[assignment]


def project_tsai_jacobian(
    points_world: NDArray[np.float64],
    f: float,
    sx: float,
    kappa1: float,
    world2cam_r: NDArray[np.float64],
    camera_position: NDArray[np.float64],
    drot: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Pixels and their analytic derivatives with respect to Tsai's parameters.

    The parameters are (f, cx, cy, sx, kappa1, rotation (3), camera position C (3)); the
    camera frame point is ``R @ (X - C)``. The rotation enters through ``drot``, the (3, 3)
    derivative of R with respect to the three rotation parameters as used by the caller
    (the right Jacobian of SO(3) for a rotation vector): d(R v)/d(rot) = -R skew(v) drot.

    Args:
        points_world: (N, 3) points, m. f: px. sx: -. kappa1: 1/px^2.
        world2cam_r: (3, 3). camera_position: (3,) optical centre in the world, m.
        drot: (3, 3) see above.

    Returns:
        pixels (N, 2) and the Jacobian (N, 2, 11) in the order f, cx, cy, sx, kappa1,
        rot(3), C(3). Points behind the camera give NaN.
    """
    v = points_world - camera_position
    pc = v @ world2cam_r.T
    z = pc[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        zi = np.where(z > 0, 1.0 / z, np.nan)
    xn, yn = pc[:, 0] * zi, pc[:, 1] * zi
    xu, yu = f * xn, f * yn
    ru2 = xu * xu + yu * yu
    t = kappa1 * ru2
    s = distort(np.ones((len(t), 1)) * np.sqrt(np.maximum(ru2, 0))[:, None], kappa1)[:, 0]
    s = np.where(ru2 > 0, s / np.sqrt(np.where(ru2 > 0, ru2, 1.0)), 1.0)
    ds_dt = -(s**3) / (1.0 + 3.0 * t * s * s)
    xd, yd = s * xu, s * yu
    # d(xd, yd) / d(xu, yu)
    g = ds_dt * kappa1 * 2.0
    a11, a12 = s + xu * g * xu, xu * g * yu
    a21, a22 = yu * g * xu, s + yu * g * yu
    n = len(points_world)
    jac = np.zeros((n, 2, 11))
    # f: xu = f xn
    dxd_df = a11 * xn + a12 * yn
    dyd_df = a21 * xn + a22 * yn
    jac[:, 0, 0], jac[:, 1, 0] = sx * dxd_df, dyd_df
    jac[:, 0, 1] = 1.0
    jac[:, 1, 2] = 1.0
    jac[:, 0, 3] = xd
    ds_dk = ds_dt * ru2
    jac[:, 0, 4], jac[:, 1, 4] = sx * xu * ds_dk, yu * ds_dk
    # d(xn, yn) / d(pc): rows (2, 3) per point
    dn_dpc = np.zeros((n, 2, 3))
    dn_dpc[:, 0, 0] = zi
    dn_dpc[:, 0, 2] = -xn * zi
    dn_dpc[:, 1, 1] = zi
    dn_dpc[:, 1, 2] = -yn * zi
    # d(u, v) / d(xn, yn) = diag(sx, 1) @ A @ f
    a = np.stack([np.stack([a11, a12], -1), np.stack([a21, a22], -1)], -2) * f
    a[:, 0, :] *= sx
    duv_dpc = a @ dn_dpc  # (N, 2, 3)
    # pc = R (X - C): d pc / d C = -R ; d pc / d rot = -R skew(v) drot
    jac[:, :, 8:11] = -duv_dpc @ world2cam_r
    sk = np.zeros((n, 3, 3))
    sk[:, 0, 1], sk[:, 0, 2] = -v[:, 2], v[:, 1]
    sk[:, 1, 0], sk[:, 1, 2] = v[:, 2], -v[:, 0]
    sk[:, 2, 0], sk[:, 2, 1] = -v[:, 1], v[:, 0]
    jac[:, :, 5:8] = -(duv_dpc @ world2cam_r) @ sk @ drot
    uv = np.column_stack([sx * xd, yd])
    return uv, jac
