"""The evaluation metrics of the paper's Table III, for one camera or T at once.

* pixel error: the 3D points projected with the calibrated camera, compared with the
  observed pixels (px);
* 3D error: the distance from each 3D point to the line of sight through its observed
  pixel (m);

and :func:`pose_errors`: the distance of each optical centre from the true one (m) and the
angle of each rotation relative to the true one (rad).

The ``*_batch`` functions take T Tsai cameras (one per Monte-Carlo trial), each with its
own M correspondences; a point behind its camera, or beyond the fold of a negative kappa1,
gives NaN there and so NaN statistics for its trial. The functions of one camera (of any
model) compute the same with the camera's own projection, which raises for such a point.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from calib.camera import TsaiCamera, TsaiCameras
from calib.checks import check_correspondences


class CameraModel(Protocol):
    """What the metrics need of a camera: projection and lines of sight."""

    def project(self, points_world: ArrayLike) -> NDArray[np.float64]: ...

    def unproject(self, pixels: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...


@dataclass(frozen=True)
class ErrorStats:
    """Mean, RMS, standard deviation and maximum of a set of non-negative errors: floats
    for one camera, (T,) arrays for T."""

    mean: float | NDArray[np.float64]
    rms: float | NDArray[np.float64]
    std: float | NDArray[np.float64]
    max: float | NDArray[np.float64]

    @classmethod
    def of(cls, errors: NDArray[np.float64]) -> ErrorStats:
        """Statistics of (M,) errors, or of (T, M) errors along M."""
        e = np.asarray(errors, dtype=float)
        stats = (e.mean(axis=-1), np.sqrt(np.mean(e**2, axis=-1)), e.std(axis=-1), e.max(axis=-1))
        return cls(*(float(s) if e.ndim == 1 else s for s in stats))


@dataclass(frozen=True)
class Metrics:
    """Table III metrics of a camera (or of T cameras) on a set of correspondences.

    Attributes:
        pixel: statistics of the reprojection error, px.
        error_3d: statistics of the point-to-line-of-sight distance, m.
        n_points: number of correspondences evaluated (per camera).
    """

    pixel: ErrorStats
    error_3d: ErrorStats
    n_points: int


@dataclass(frozen=True)
class PoseErrors:
    """Errors of T cameras against the truth.

    Attributes:
        position_m: (T,) distance of each optical centre from the true one, m.
        rotation_rad: (T,) angle of the rotation taking the true camera frame to each
            camera's frame, rad.
    """

    position_m: NDArray[np.float64]
    rotation_rad: NDArray[np.float64]


def _distances(projected: NDArray[np.float64], pixels: NDArray[np.float64]) -> NDArray:
    """(..., M) distance between projected and observed (..., M, 2) pixels, px."""
    return np.linalg.norm(projected - pixels, axis=-1)


def _off_lines(
    points: NDArray[np.float64], origins: NDArray[np.float64], dirs: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(..., M) distance of (..., M, 3) points from the lines of sight, m."""
    rel = points - origins
    along = np.sum(rel * dirs, axis=-1, keepdims=True)
    return np.linalg.norm(rel - along * dirs, axis=-1)


def _correspondences(
    cameras: TsaiCameras, points_3d: ArrayLike, pixels: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(T, M, 3) or shared (M, 3) points and (T, M, 2) pixels -> both as (T, M, ...)."""
    n_t = len(cameras)
    uv = np.asarray(pixels, dtype=float)
    if uv.ndim != 3 or uv.shape[0] != n_t or uv.shape[2] != 2:
        raise ValueError(f"pixels must have shape ({n_t}, M, 2), got {uv.shape}")
    m = uv.shape[1]
    p3 = np.asarray(points_3d, dtype=float)
    if p3.shape not in ((n_t, m, 3), (m, 3)):
        raise ValueError(f"points must have shape ({n_t}, {m}, 3) or ({m}, 3), got {p3.shape}")
    return np.broadcast_to(p3, (n_t, m, 3)), uv


def pixel_errors_batch(
    cameras: TsaiCameras, points_3d: ArrayLike, pixels: ArrayLike
) -> NDArray[np.float64]:
    """(T, M) distance between each trial's projected 3D points and observed pixels, px.

    Args:
        cameras: T cameras.
        points_3d: (T, M, 3) world points, m; or (M, 3) shared.
        pixels: (T, M, 2) observed pixels.
    """
    p3, uv = _correspondences(cameras, points_3d, pixels)
    return _distances(cameras.project_or_nan(p3), uv)


def errors_3d_batch(
    cameras: TsaiCameras, points_3d: ArrayLike, pixels: ArrayLike
) -> NDArray[np.float64]:
    """(T, M) distance from each 3D point to the line of sight through its pixel, m.

    Args: as :func:`pixel_errors_batch`.
    """
    p3, uv = _correspondences(cameras, points_3d, pixels)
    return _off_lines(p3, *cameras.unproject(uv))


def evaluate_batch(cameras: TsaiCameras, points_3d: ArrayLike, pixels: ArrayLike) -> Metrics:
    """Table III metrics (pixel error and 3D error) of T cameras, each on its M points;
    the statistics are (T,) arrays.

    Args:
        cameras: T cameras (``TsaiBatchResult.cameras`` for a batch of calibrations).
        points_3d: (T, M, 3) world points, m; or (M, 3) shared.
        pixels: (T, M, 2) observed pixels.
    """
    p3, uv = _correspondences(cameras, points_3d, pixels)
    return Metrics(
        ErrorStats.of(pixel_errors_batch(cameras, p3, uv)),
        ErrorStats.of(errors_3d_batch(cameras, p3, uv)),
        uv.shape[1],
    )


def pixel_errors(camera: CameraModel, points_3d: ArrayLike, pixels: ArrayLike) -> NDArray:
    """(N,) distance between projected 3D points and observed pixels, px (raises where
    :func:`pixel_errors_batch` gives NaN)."""
    p3, uv = check_correspondences(points_3d, pixels)
    return _distances(camera.project(p3), uv)


def errors_3d(camera: CameraModel, points_3d: ArrayLike, pixels: ArrayLike) -> NDArray:
    """(N,) distance from each 3D point to the line of sight through its pixel, m."""
    p3, uv = check_correspondences(points_3d, pixels)
    return _off_lines(p3, *camera.unproject(uv))


def evaluate(camera: CameraModel, points_3d: ArrayLike, pixels: ArrayLike) -> Metrics:
    """Table III metrics (pixel error and 3D error) of ``camera`` on N correspondences.

    Args:
        camera: a calibrated camera (Tsai or OpenCV model).
        points_3d: (N, 3) world points, m.
        pixels: (N, 2) observed pixels.
    """
    p3, uv = check_correspondences(points_3d, pixels)
    return Metrics(
        ErrorStats.of(pixel_errors(camera, p3, uv)),
        ErrorStats.of(errors_3d(camera, p3, uv)),
        len(p3),
    )


def pose_errors(cameras: TsaiCameras, truth: TsaiCamera | TsaiCameras) -> PoseErrors:
    """Position error (m) and rotation error (rad) of T cameras against the true camera.

    Args:
        cameras: T cameras.
        truth: the true camera, or T true cameras (one per trial).
    """
    if isinstance(truth, TsaiCamera):
        r_true, c_true = truth.world2cam_r[None], truth.position[None]
    else:
        r_true, c_true = truth.world2cam_r, truth.position
    relative = cameras.world2cam_r @ np.swapaxes(r_true, -1, -2)
    return PoseErrors(
        np.linalg.norm(cameras.position - c_true, axis=1),
        Rotation.from_matrix(relative).magnitude(),
    )
