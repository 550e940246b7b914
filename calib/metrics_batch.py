"""The metrics of the paper's Table III, and the errors against a true camera, for T
cameras at once (one per Monte-Carlo trial).

Per trial, the same quantities as :func:`calib.metrics.evaluate`:

* pixel error: trial k's 3D points projected with its camera, against its observed
  pixels (px);
* 3D error: the distance from each 3D point to the line of sight through its observed
  pixel (m), the pixel undistorted in closed form;

and :func:`pose_errors`: the distance of each optical centre from the true one (m) and the
angle of each rotation relative to the true one (rad). A point behind its camera, or
beyond the fold of a negative kappa1, gives NaN (where :func:`calib.metrics.evaluate`
raises) and so NaN statistics for its trial.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from calib.camera import TsaiCamera
from calib.camera_batch import TsaiCameras


@dataclass(frozen=True)
class ErrorStatsBatch:
    """Per trial: mean, RMS, standard deviation and maximum of non-negative errors, (T,)
    each (as :class:`calib.metrics.ErrorStats`)."""

    mean: NDArray[np.float64]
    rms: NDArray[np.float64]
    std: NDArray[np.float64]
    max: NDArray[np.float64]

    @classmethod
    def of(cls, errors: NDArray[np.float64]) -> ErrorStatsBatch:
        """Statistics of (T, M) errors along M."""
        e = np.asarray(errors, dtype=float)
        return cls(e.mean(axis=1), np.sqrt(np.mean(e**2, axis=1)), e.std(axis=1), e.max(axis=1))


@dataclass(frozen=True)
class MetricsBatch:
    """Table III metrics of T cameras, each on its own M correspondences.

    Attributes:
        pixel: per trial statistics of the reprojection error, px.
        error_3d: per trial statistics of the point-to-line-of-sight distance, m.
        n_points: correspondences per trial, M.
    """

    pixel: ErrorStatsBatch
    error_3d: ErrorStatsBatch
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
    return np.linalg.norm(cameras.project_or_nan(p3) - uv, axis=-1)


def errors_3d_batch(
    cameras: TsaiCameras, points_3d: ArrayLike, pixels: ArrayLike
) -> NDArray[np.float64]:
    """(T, M) distance from each 3D point to the line of sight through its pixel, m.

    Args: as :func:`pixel_errors_batch`.
    """
    p3, uv = _correspondences(cameras, points_3d, pixels)
    origins, dirs = cameras.unproject(uv)
    rel = p3 - origins
    along = np.sum(rel * dirs, axis=-1, keepdims=True)
    return np.linalg.norm(rel - along * dirs, axis=-1)


def evaluate_batch(cameras: TsaiCameras, points_3d: ArrayLike, pixels: ArrayLike) -> MetricsBatch:
    """Table III metrics (pixel error and 3D error) of T cameras, each on its M points.

    Trial k's statistics equal those of ``calib.metrics.evaluate(cameras.camera(k),
    points_3d[k], pixels[k])``.

    Args:
        cameras: T cameras (``TsaiBatchResult.cameras`` for a batch of calibrations).
        points_3d: (T, M, 3) world points, m; or (M, 3) shared.
        pixels: (T, M, 2) observed pixels.
    """
    p3, uv = _correspondences(cameras, points_3d, pixels)
    return MetricsBatch(
        ErrorStatsBatch.of(pixel_errors_batch(cameras, p3, uv)),
        ErrorStatsBatch.of(errors_3d_batch(cameras, p3, uv)),
        uv.shape[1],
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
