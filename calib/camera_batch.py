"""Tsai's camera model for T cameras at once, as arrays over a leading trial axis.

The model is that of :mod:`calib.camera` (pinhole, Tsai's first-order radial distortion,
horizontal scale factor sx); here every parameter carries a leading axis of length T (one
camera per Monte-Carlo trial) and every point set a shape (T, N, ...): trial k's camera
sees trial k's points. No computation mixes trials, so trial k of a batch is computed
exactly as a batch of that trial alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.camera import TsaiCamera
from calib.checks import check_image_size
from calib.distortion import distort, distortion_scale, undistort


@dataclass(frozen=True, eq=False)
class TsaiCameras:
    """T cameras of Tsai's model, one per trial (the attributes of :class:`TsaiCamera`).

    Attributes:
        f: (T,) focal length / pixel height, px.
        cx, cy: (T,) image centre, px (OpenCV convention).
        kappa1: (T,) radial distortion, 1/px^2 (Tsai's direction).
        sx: (T,) horizontal scale factor.
        world2cam_r: (T, 3, 3) rotations from the world to the camera frame.
        position: (T, 3) optical centres in the world frame, m.
        image_size: (width, height), px, shared by all T cameras.
    """

    f: NDArray[np.float64]
    cx: NDArray[np.float64]
    cy: NDArray[np.float64]
    kappa1: NDArray[np.float64]
    sx: NDArray[np.float64]
    world2cam_r: NDArray[np.float64] = field(repr=False)
    position: NDArray[np.float64] = field(repr=False)
    image_size: tuple[int, int] = (320, 240)

    def __post_init__(self) -> None:
        r = np.asarray(self.world2cam_r, dtype=float)
        if r.ndim != 3 or r.shape[1:] != (3, 3):
            raise ValueError(f"world2cam_r must have shape (T, 3, 3), got {r.shape}")
        n = len(r)
        c = np.asarray(self.position, dtype=float)
        if c.shape != (n, 3):
            raise ValueError(f"position must have shape ({n}, 3), got {c.shape}")
        for name in ("f", "cx", "cy", "kappa1", "sx"):
            a = np.broadcast_to(np.asarray(getattr(self, name), dtype=float), (n,))
            if not np.isfinite(a).all():
                raise ValueError(f"camera parameter {name} must be finite")
            object.__setattr__(self, name, a)
        if (self.f <= 0).any() or (self.sx <= 0).any():
            raise ValueError("f and sx must be positive")
        gram = r @ np.swapaxes(r, -1, -2)
        if not np.allclose(gram, np.eye(3), atol=1e-9) or (np.linalg.det(r) < 0).any():
            raise ValueError("world2cam_r must hold proper rotation matrices")
        if not np.isfinite(c).all():
            raise ValueError("position must be finite")
        object.__setattr__(self, "world2cam_r", r)
        object.__setattr__(self, "position", c)
        object.__setattr__(self, "image_size", check_image_size(self.image_size))

    @classmethod
    def from_cameras(cls, cameras: Sequence[TsaiCamera]) -> TsaiCameras:
        """Stack T cameras of the same image size."""
        sizes = {c.image_size for c in cameras}
        if len(sizes) != 1:
            raise ValueError(f"the cameras must share one image size, got {sorted(sizes)}")

        def col(name: str) -> NDArray[np.float64]:
            return np.array([getattr(c, name) for c in cameras], dtype=float)

        return cls(
            col("f"),
            col("cx"),
            col("cy"),
            col("kappa1"),
            col("sx"),
            np.stack([c.world2cam_r for c in cameras]),
            np.stack([c.position for c in cameras]),
            sizes.pop(),
        )

    def __len__(self) -> int:
        return len(self.world2cam_r)

    @property
    def world2cam_t(self) -> NDArray[np.float64]:
        """(T, 3) translations from the world to the camera frame, m."""
        return -(self.world2cam_r @ self.position[:, :, None])[:, :, 0]

    def camera(self, k: int) -> TsaiCamera:
        """Camera k as a :class:`TsaiCamera`."""
        r = self.world2cam_r[k]
        return TsaiCamera(
            float(self.f[k]),
            float(self.cx[k]),
            float(self.cy[k]),
            float(self.kappa1[k]),
            float(self.sx[k]),
            r,
            -r @ self.position[k],
            self.image_size,
        )

    def to_camera_frame(self, points_world: ArrayLike) -> NDArray[np.float64]:
        """(T, N, 3) world points -> (T, N, 3) points in each camera's frame, m."""
        p = _points(points_world, len(self))
        return (p - self.position[:, None, :]) @ np.swapaxes(self.world2cam_r, -1, -2)

    def project_or_nan(self, points_world: ArrayLike) -> NDArray[np.float64]:
        """(T, N, 3) world points (m) -> (T, N, 2) distorted pixels; NaN rows where a point
        lies behind its camera or beyond the fold of a negative kappa1."""
        pc = self.to_camera_frame(points_world)
        z = pc[..., 2:3]
        with np.errstate(divide="ignore", invalid="ignore"):
            xy_u = np.where(z > 0, self.f[:, None, None] * pc[..., :2] / z, np.nan)
        xy_d = distort(xy_u, self.kappa1[:, None])
        u = self.sx[:, None] * xy_d[..., 0] + self.cx[:, None]
        return np.stack([u, xy_d[..., 1] + self.cy[:, None]], axis=-1)

    def pixels_to_normalized(self, pixels: ArrayLike) -> NDArray[np.float64]:
        """(T, N, 2) distorted pixels -> (T, N, 2) undistorted normalised coordinates."""
        uv = _pixels(pixels, len(self))
        xd = (uv[..., 0] - self.cx[:, None]) / self.sx[:, None]
        xy_d = np.stack([xd, uv[..., 1] - self.cy[:, None]], axis=-1)
        return undistort(xy_d, self.kappa1[:, None]) / self.f[:, None, None]

    def unproject(self, pixels: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Lines of sight through (T, N, 2) pixels.

        Returns:
            origins: (T, N, 3) each camera's optical centre in the world frame, m.
            directions: (T, N, 3) unit directions in the world frame.
        """
        xy = self.pixels_to_normalized(pixels)
        rays = np.concatenate([xy, np.ones((*xy.shape[:-1], 1))], axis=-1)
        rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
        directions = rays @ self.world2cam_r
        origins = np.broadcast_to(self.position[:, None, :], directions.shape).copy()
        return origins, directions


def _points(points_world: ArrayLike, n: int) -> NDArray[np.float64]:
    p = np.asarray(points_world, dtype=float)
    if p.ndim != 3 or p.shape[0] != n or p.shape[2] != 3:
        raise ValueError(f"points must have shape ({n}, N, 3), got {p.shape}")
    return p


def _pixels(pixels: ArrayLike, n: int) -> NDArray[np.float64]:
    uv = np.asarray(pixels, dtype=float)
    if uv.ndim != 3 or uv.shape[0] != n or uv.shape[2] != 2:
        raise ValueError(f"pixels must have shape ({n}, N, 2), got {uv.shape}")
    return uv


def project_tsai_jacobian_batch(
    points_world: NDArray[np.float64],
    f: NDArray[np.float64],
    cx: NDArray[np.float64],
    cy: NDArray[np.float64],
    sx: NDArray[np.float64],
    kappa1: NDArray[np.float64],
    world2cam_r: NDArray[np.float64],
    camera_position: NDArray[np.float64],
    drot: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Pixels of T cameras and their analytic derivatives, without input checks.

    :func:`calib.camera.project_tsai_jacobian` for T cameras, each with its own N points.
    The camera frame point is ``R @ (X - C)``; the rotation enters through ``drot``, the
    derivative of R with respect to the caller's three rotation parameters (the right
    Jacobian of SO(3) for a rotation vector).

    Args:
        points_world: (T, N, 3) points, m.
        f, cx, cy: (T,) px. sx: (T,). kappa1: (T,) 1/px^2.
        world2cam_r: (T, 3, 3). camera_position: (T, 3) optical centres, m.
        drot: (T, 3, 3), see above.

    Returns:
        pixels (T, N, 2) (with cx, cy) and the Jacobian (T, N, 2, 11) in the order f, cx,
        cy, sx, kappa1, rot(3), C(3). Points behind their camera give NaN.
    """
    n_t, n = points_world.shape[:2]
    pc = (points_world - camera_position[:, None, :]) @ np.swapaxes(world2cam_r, -1, -2)
    z = pc[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        zi = np.where(z > 0, 1.0 / z, np.nan)
    xn, yn = pc[..., 0] * zi, pc[..., 1] * zi
    fb, sxb, kb = f[:, None], sx[:, None], kappa1[:, None]
    xu, yu = fb * xn, fb * yn
    ru2 = xu * xu + yu * yu
    t = kb * ru2
    s = distortion_scale(t)
    ds_dt = -(s**3) / (1.0 + 3.0 * t * s * s)
    xd, yd = s * xu, s * yu
    # d(xd, yd) / d(xu, yu) = s I + g (xu, yu)(xu, yu)^T: symmetric
    g = 2.0 * kb * ds_dt
    a11, a12, a22 = s + g * xu * xu, g * xu * yu, s + g * yu * yu
    jac = np.empty((n_t, n, 2, 11))
    jac[..., 1, 1] = jac[..., 0, 2] = jac[..., 1, 3] = 0.0
    jac[..., 0, 0] = sxb * (a11 * xn + a12 * yn)
    jac[..., 1, 0] = a12 * xn + a22 * yn
    jac[..., 0, 1] = 1.0
    jac[..., 1, 2] = 1.0
    jac[..., 0, 3] = xd
    ds_dk = ds_dt * ru2
    jac[..., 0, 4] = sxb * xu * ds_dk
    jac[..., 1, 4] = yu * ds_dk
    # A row of d(u, v) / d pc is (f / z) (b0, b1, -(b0 xn + b1 yn)), (b0, b1) the row of
    # diag(sx, 1) A. d pc / d C = -R. A rotation dw of the camera frame (pc -> pc + dw x pc)
    # moves the pixel by -(m x pc) . dw, and m x pc = f (b1 (1 + yn^2) + b0 xn yn,
    # -(b0 (1 + xn^2) + b1 xn yn), b0 yn - b1 xn); dw = R drot d(rot).
    rows = ((sxb * a11, sxb * a12), (a12, a22))
    m = np.empty((n_t, n, 2, 3))
    frame = np.empty((n_t, n, 2, 3))
    c = fb * zi
    xy, xx, yy = xn * yn, 1.0 + xn * xn, 1.0 + yn * yn
    for i, (b0, b1) in enumerate(rows):
        m[..., i, 0], m[..., i, 1] = c * b0, c * b1
        m[..., i, 2] = -(m[..., i, 0] * xn + m[..., i, 1] * yn)
        frame[..., i, 0] = fb * (b1 * yy + b0 * xy)
        frame[..., i, 1] = -fb * (b0 * xx + b1 * xy)
        frame[..., i, 2] = fb * (b0 * yn - b1 * xn)
    jac[..., 8:11] = -(m.reshape(n_t, 2 * n, 3) @ world2cam_r).reshape(n_t, n, 2, 3)
    dw = world2cam_r @ drot
    jac[..., 5:8] = -(frame.reshape(n_t, 2 * n, 3) @ dw).reshape(n_t, n, 2, 3)
    uv = np.stack([sxb * xd + cx[:, None], yd + cy[:, None]], axis=-1)
    return uv, jac
