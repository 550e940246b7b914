"""Is each camera still where its calibration says? ``twin check``'s procedure, written
against the hardware-abstraction interface as the campaign is.

- :mod:`.procedure`: :func:`check_cameras`: the campaign's steps with a few stops per
  camera (:mod:`.strategy`: from the first station or the camera's visit station;
  :mod:`.collection`: the data taken, nothing calibrated);
- :mod:`.gathering`: each data point with its pixel noise and the parent's pose;
- :mod:`.covariance`: the data's joint covariance, in 3D and in the image;
- :mod:`.consistency`: the chi-square test of the pixels against the calibrated model;
- :mod:`.repose`: the camera re-posed from the same points, intrinsics kept;
- :mod:`.assessment`: the verdict on one camera.
"""

from twin.campaign.check.assessment import CameraCheck, assess
from twin.campaign.check.consistency import DEFAULT_FALSE_ALARM_RATE, Consistency
from twin.campaign.check.covariance import MIN_PIXEL_SIGMA
from twin.campaign.check.procedure import (
    DEFAULT_STOPS,
    MAX_STOPS,
    MIN_STOPS,
    CheckOutcome,
    check_cameras,
    check_min_pixel_sigma,
    check_stops,
)
from twin.campaign.check.repose import Repose

__all__ = [
    "DEFAULT_FALSE_ALARM_RATE",
    "DEFAULT_STOPS",
    "MAX_STOPS",
    "MIN_PIXEL_SIGMA",
    "MIN_STOPS",
    "CameraCheck",
    "CheckOutcome",
    "Consistency",
    "Repose",
    "assess",
    "check_cameras",
    "check_min_pixel_sigma",
    "check_stops",
]
