"""One camera's check: its data against its calibrated model, and its new pose."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from calib.camera import TsaiCamera
from calib.camera_covariance import camera_jacobian
from twin.campaign.check.consistency import (
    DEFAULT_FALSE_ALARM_RATE,
    Consistency,
    chi_square_test,
)
from twin.campaign.check.covariance import MIN_PIXEL_SIGMA, data_covariance, stacked
from twin.campaign.check.gathering import CheckPoint
from twin.campaign.check.repose import Repose, repose


@dataclass(frozen=True)
class CameraCheck:
    """The verdict on one camera.

    Attributes:
        camera: its name.
        stops: the child's stops that gave LED points. points: LED points used.
        consistency: the chi-square test against the calibrated model.
        repose: the camera re-posed from the same points (intrinsics kept), with how far
            it moved and the covariance of that; None when the points cannot give a pose
            (``repose_error`` says why).
        calibration_known: whether the calibration's covariance was weighed (else the
            calibrated model was taken as exact).
    """

    camera: str
    stops: int
    points: int
    consistency: Consistency
    repose: Repose | None
    repose_error: str = ""
    calibration_known: bool = True

    @property
    def moved(self) -> bool:
        """Whether the chi-square test says the camera moved."""
        return self.consistency.moved


def assess(
    name: str,
    calibrated: TsaiCamera,
    points: Sequence[CheckPoint],
    false_alarm_rate: float = DEFAULT_FALSE_ALARM_RATE,
    calibration_cov: NDArray[np.float64] | None = None,
    min_pixel_sigma: float = MIN_PIXEL_SIGMA,
) -> CameraCheck:
    """Test a camera's check data against its calibration and re-pose it.

    Args:
        name: the camera. calibrated: its calibrated model (pose in W).
        points: its check data, one entry per stop of the child.
        false_alarm_rate: of the chi-square test, in (0, 1).
        calibration_cov: (11, 11) the calibrated camera's covariance
            (:data:`calib.camera_covariance.CAMERA_PARAMETERS`); None: taken as exact.
        min_pixel_sigma: the least standard deviation of a pixel coordinate, px.

    Raises:
        ValueError: no points, a bad false-alarm rate, or an LED behind the camera.
    """
    leds, pixels = stacked(points)
    if not len(leds):
        raise ValueError(f"no LED points of camera {name!r} to check it with")
    data_cov = data_covariance(calibrated, points, min_pixel_sigma)
    model_cov = 0.0
    if calibration_cov is not None:
        jac = camera_jacobian(calibrated, leds)
        model_cov = jac @ calibration_cov @ jac.T
    test = chi_square_test(calibrated, leds, pixels, data_cov + model_cov, false_alarm_rate)
    try:
        new: Repose | None = repose(calibrated, leds, pixels, data_cov, calibration_cov)
        error = ""
    except ValueError as exc:
        new, error = None, str(exc)
    return CameraCheck(name, len(points), len(leds), test, new, error, calibration_cov is not None)
