"""What the trials of a batch gave: each visit's calibration and the parent's final error,
as (T, ...) arrays, and the analytic prediction of a camera's error from the parent's pose."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray


class ParentPose(Protocol):
    """The parent's pose estimate in T trials: (T, 3) translation, m, and (T, 4, 4)
    covariance of (yaw, x, y, z)."""

    @property
    def translation(self) -> NDArray[np.float64]: ...

    @property
    def covariance(self) -> NDArray[np.float64]: ...


@dataclass
class BatchOutcome:
    """What T trials of a plan gave.

    Attributes:
        calibrations: (camera, visit) -> the visit's calibrations, with its errors (see
            :class:`VisitOutcome`).
        parent_error: (T, 3) the parent's final estimate minus its truth, m.
        parent_covariance: (T, 3, 3) its predicted covariance, m^2.
        distance: (T,) the parent's travel by its own estimates, m.
        failures: (T,) consistency tests failed (the geometric fidelity would measure again).
    """

    calibrations: dict[tuple[str, int], VisitOutcome]
    parent_error: NDArray[np.float64]
    parent_covariance: NDArray[np.float64]
    distance: NDArray[np.float64]
    failures: NDArray[np.int64]


@dataclass
class VisitOutcome:
    """A visit's calibration in T trials: (T,) arrays unless said.

    Attributes:
        points: LED points used (fewer where a trial gave up stops). distance: the
            parent's travel at the calibration, m.
        position_error: m. rotation_error: rad (NaN where not calibrated).
        position_offset: (T, 3) calibrated minus true camera centre in W, m (NaN where not
            calibrated).
        world_pixel, world_3d: Table III against the reference set (px, m), NaN without one.
        local_pixel, local_3d: Table III against the visit's own data (px, m).
        predicted_transfer, predicted_calibration: the analytic prediction's RMS 3D
            position error from the parent's pose and from the calibration itself, m.
        calibrated: whether each trial's calibration succeeded.
    """

    points: NDArray[np.int64]
    distance: NDArray[np.float64]
    position_error: NDArray[np.float64]
    rotation_error: NDArray[np.float64]
    position_offset: NDArray[np.float64]
    world_pixel: NDArray[np.float64]
    world_3d: NDArray[np.float64]
    local_pixel: NDArray[np.float64]
    local_3d: NDArray[np.float64]
    predicted_transfer: NDArray[np.float64]
    predicted_calibration: NDArray[np.float64]
    calibrated: NDArray[np.bool_]


def transfer_rms(parent: ParentPose, camera: NDArray[np.float64]) -> NDArray[np.float64]:
    """(T,) RMS 3D error of a camera's centre (T, 3) from the parent's pose error at the
    station (:func:`twin.montecarlo.prediction.camera_position_covariance`), m."""
    lever = camera - parent.translation
    jac = np.zeros((len(lever), 3, 4))
    jac[:, 0, 0], jac[:, 1, 0] = -lever[:, 1], lever[:, 0]
    jac[:, :, 1:] = np.eye(3)
    cov = jac @ parent.covariance @ np.swapaxes(jac, 1, 2)
    return np.sqrt(np.trace(cov, axis1=1, axis2=2))
