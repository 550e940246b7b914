"""The evaluation metrics of the paper's Table III.

* pixel error: the 3D points projected with the calibrated camera, compared with the
  observed pixels (px);
* 3D error: the distance from each 3D point to the line of sight through its observed
  pixel (m).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.checks import check_correspondences


class CameraModel(Protocol):
    """What the metrics need of a camera: projection and lines of sight."""

    def project(self, points_world: ArrayLike) -> NDArray[np.float64]: ...

    def unproject(self, pixels: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...


@dataclass(frozen=True)
class ErrorStats:
    """Mean, RMS, standard deviation and maximum of a set of non-negative errors."""

    mean: float
    rms: float
    std: float
    max: float

    @classmethod
    def of(cls, errors: NDArray[np.float64]) -> ErrorStats:
        e = np.asarray(errors, dtype=float)
        return cls(float(e.mean()), float(np.sqrt(np.mean(e**2))), float(e.std()), float(e.max()))


@dataclass(frozen=True)
class Metrics:
    """Table III metrics of a camera on a set of correspondences.

    Attributes:
        pixel: statistics of the reprojection error, px.
        error_3d: statistics of the point-to-line-of-sight distance, m.
        n_points: number of correspondences evaluated.
    """

    pixel: ErrorStats
    error_3d: ErrorStats
    n_points: int


def pixel_errors(camera: CameraModel, points_3d: ArrayLike, pixels: ArrayLike) -> NDArray:
    """(N,) distance between projected 3D points and observed pixels, px."""
    p3, uv = check_correspondences(points_3d, pixels)
    return np.linalg.norm(camera.project(p3) - uv, axis=1)


def errors_3d(camera: CameraModel, points_3d: ArrayLike, pixels: ArrayLike) -> NDArray:
    """(N,) distance from each 3D point to the line of sight through its pixel, m."""
    p3, uv = check_correspondences(points_3d, pixels)
    origins, dirs = camera.unproject(uv)
    rel = p3 - origins
    along = np.sum(rel * dirs, axis=1, keepdims=True)
    return np.linalg.norm(rel - along * dirs, axis=1)


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
