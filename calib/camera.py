"""Tsai's camera model: pinhole with first-order radial distortion and a horizontal scale.

A world point X (m) maps to a pixel (u, v) by

    [x_c, y_c, z_c] = R @ X + t                   (R, t: world-to-camera, OpenCV frame)
    (x_u, y_u) = f * (x_c, y_c) / z_c             (px, undistorted)
    (x_u, y_u) = (x_d, y_d) * (1 + kappa1 r_d^2)  (Tsai's distortion, solved for x_d, y_d)
    u = sx * x_d + cx,  v = y_d + cy              (px, OpenCV pixel convention)

Pixel (0, 0) is the centre of the top-left pixel. The camera frame is OpenCV's: x right,
y down, z forward.

The model is computed once, by functions over arrays with leading axes ``...`` (none for
one camera, (T,) for one camera per Monte-Carlo trial): :class:`TsaiCamera` is one camera,
:class:`TsaiCameras` T of them, and both project with the same functions. No computation
mixes trials, so trial k of a batch is computed exactly as that camera alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.checks import check_image_size, check_pixels, check_points_3d
from calib.distortion import distort, undistort
from calib.rotation import euler2matrix, look_at_world2cam, matrix2euler


def per_point(value: float | ArrayLike) -> NDArray[np.float64]:
    """A parameter of shape (...) -> (..., 1), to broadcast against N points."""
    return np.asarray(value, dtype=float)[..., None]


def project_tsai(
    points_world: NDArray[np.float64],
    f: float | NDArray[np.float64],
    cx: float | NDArray[np.float64],
    cy: float | NDArray[np.float64],
    sx: float | NDArray[np.float64],
    kappa1: float | NDArray[np.float64],
    world2cam_r: NDArray[np.float64],
    world2cam_t: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Project world points with Tsai's model, without input checks.

    Args:
        points_world: (..., N, 3) points, m: (N, 3) for one camera, (T, N, 3) for T.
        f: focal length, px. cx, cy: image centre, px. sx: horizontal scale factor.
        kappa1: radial distortion, 1/px^2. Each a float or of shape (...).
        world2cam_r: (..., 3, 3) rotation. world2cam_t: (..., 3) translation, m.

    Returns:
        (..., N, 2) pixels. Points with z_c <= 0 or beyond the distortion fold give NaN.
    """
    pc = points_world @ np.swapaxes(world2cam_r, -1, -2) + world2cam_t[..., None, :]
    z = pc[..., 2:3]
    with np.errstate(divide="ignore", invalid="ignore"):
        xy_u = np.where(z > 0, per_point(f)[..., None] * pc[..., :2] / z, np.nan)
    xy_d = distort(xy_u, per_point(kappa1))
    u = per_point(sx) * xy_d[..., 0] + per_point(cx)
    return np.stack([u, xy_d[..., 1] + per_point(cy)], axis=-1)


def pixels_to_normalized(
    pixels: NDArray[np.float64],
    f: float | NDArray[np.float64],
    cx: float | NDArray[np.float64],
    cy: float | NDArray[np.float64],
    sx: float | NDArray[np.float64],
    kappa1: float | NDArray[np.float64],
) -> NDArray[np.float64]:
    """(..., N, 2) distorted pixels -> (..., N, 2) undistorted normalised coordinates
    x_c/z_c, without input checks (parameters as :func:`project_tsai`)."""
    xd = (pixels[..., 0] - per_point(cx)) / per_point(sx)
    xy_d = np.stack([xd, pixels[..., 1] - per_point(cy)], axis=-1)
    return undistort(xy_d, per_point(kappa1)) / per_point(f)[..., None]


def lines_of_sight(
    normalized: NDArray[np.float64], world2cam_r: NDArray[np.float64], position: NDArray
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(..., N, 2) normalised coordinates, (..., 3, 3) rotations and (..., 3) optical
    centres (m) -> the (..., N, 3) origins (m) and unit directions of the lines of sight."""
    rays = np.concatenate([normalized, np.ones((*normalized.shape[:-1], 1))], axis=-1)
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    directions = rays @ world2cam_r
    origins = np.broadcast_to(position[..., None, :], directions.shape).copy()
    return origins, directions


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
        return pixels_to_normalized(check_pixels(pixels), *self._intrinsics())

    def unproject(self, pixels: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Lines of sight through (N, 2) pixels.

        Returns:
            origins: (N, 3) the optical centre in the world frame, m (same for every row).
            directions: (N, 3) unit directions in the world frame.
        """
        return lines_of_sight(self.pixels_to_normalized(pixels), self.world2cam_r, self.position)

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
        """(f, cx, cy, sx, kappa1), the order of :func:`project_tsai`."""
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
        world2cam_t: (T, 3) translations from the world to the camera frame, m; None
            gives ``-R @ position``.
    """

    f: NDArray[np.float64]
    cx: NDArray[np.float64]
    cy: NDArray[np.float64]
    kappa1: NDArray[np.float64]
    sx: NDArray[np.float64]
    world2cam_r: NDArray[np.float64] = field(repr=False)
    position: NDArray[np.float64] = field(repr=False)
    image_size: tuple[int, int] = (320, 240)
    world2cam_t: NDArray[np.float64] = field(default=None, repr=False)  # type: ignore[assignment]

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
        if self.world2cam_t is None:
            t = -(r @ c[:, :, None])[:, :, 0]
        else:
            t = np.asarray(self.world2cam_t, dtype=float)
            if t.shape != (n, 3):
                raise ValueError(f"world2cam_t must have shape ({n}, 3), got {t.shape}")
        object.__setattr__(self, "world2cam_r", r)
        object.__setattr__(self, "position", c)
        object.__setattr__(self, "world2cam_t", t)
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
            np.stack([c.world2cam_t for c in cameras]),
        )

    def __len__(self) -> int:
        return len(self.world2cam_r)

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
            self.world2cam_t[k],
            self.image_size,
        )

    def to_camera_frame(self, points_world: ArrayLike) -> NDArray[np.float64]:
        """(T, N, 3) world points -> (T, N, 3) points in each camera's frame, m."""
        p = _points(points_world, len(self))
        return p @ np.swapaxes(self.world2cam_r, -1, -2) + self.world2cam_t[:, None, :]

    def project_or_nan(self, points_world: ArrayLike) -> NDArray[np.float64]:
        """(T, N, 3) world points (m) -> (T, N, 2) distorted pixels; NaN rows where a point
        lies behind its camera or beyond the fold of a negative kappa1."""
        p = _points(points_world, len(self))
        return project_tsai(p, *self._intrinsics(), self.world2cam_r, self.world2cam_t)

    def pixels_to_normalized(self, pixels: ArrayLike) -> NDArray[np.float64]:
        """(T, N, 2) distorted pixels -> (T, N, 2) undistorted normalised coordinates."""
        return pixels_to_normalized(_pixels(pixels, len(self)), *self._intrinsics())

    def unproject(self, pixels: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Lines of sight through (T, N, 2) pixels.

        Returns:
            origins: (T, N, 3) each camera's optical centre in the world frame, m.
            directions: (T, N, 3) unit directions in the world frame.
        """
        return lines_of_sight(self.pixels_to_normalized(pixels), self.world2cam_r, self.position)

    def _intrinsics(self) -> tuple[NDArray[np.float64], ...]:
        """(f, cx, cy, sx, kappa1), each (T,), the order of :func:`project_tsai`."""
        return self.f, self.cx, self.cy, self.sx, self.kappa1


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
