"""The covariance of a camera calibrated from a station's data, in the terms of
:data:`calib.camera_covariance.CAMERA_PARAMETERS`, in W.

The calibration (:func:`calib.tsai.calibrate_tsai`) fits all 11 parameters by unweighted
least squares; its errors come from the data's: the detector's pixel noise, each stop's
marker pose, and the parent's pose at the station, shared by every point (CPS's error of
the station, which moves the calibrated camera with the points). With J the pixels'
derivatives with respect to the camera and S the data's (2N, 2N) covariance
(:func:`twin.campaign.check.covariance.data_covariance`):

    cov = A S A^T,    A = (J^T J)^-1 J^T.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from calib.camera import TsaiCamera
from calib.camera_covariance import camera_jacobian
from twin.campaign.check.covariance import MIN_PIXEL_SIGMA, data_covariance, stacked
from twin.campaign.check.gathering import CheckPoint


def calibration_covariance(
    camera: TsaiCamera, points: Sequence[CheckPoint], min_sigma_px: float = MIN_PIXEL_SIGMA
) -> NDArray[np.float64]:
    """(11, 11) covariance of ``camera`` calibrated from ``points`` (its data, as logged;
    the pixels' standard deviation at least ``min_sigma_px``).

    Raises:
        ValueError: no points, or too few to determine the 11 parameters.
    """
    leds, _ = stacked(points)
    if 2 * len(leds) < 11:
        raise ValueError(f"{len(leds)} points cannot determine a camera's 11 parameters")
    a = np.linalg.pinv(camera_jacobian(camera, leds))
    cov = a @ data_covariance(camera, points, min_sigma_px) @ a.T
    return 0.5 * (cov + cov.T)
