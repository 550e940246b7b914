"""LED detection: sub-pixel LED positions from a switched sequence of camera frames.

A child robot switches its LEDs by a known :class:`SwitchingSequence`; :func:`detect_leds`
subtracts LED-off from LED-on frames, matches every blob against each LED's on/off code and
returns one :class:`LedDetection` per LED: a sub-pixel position with its predicted
uncertainty, or a :class:`DetectionFailure` saying why there is none. Pure numpy / scipy /
OpenCV: it works on rendered and real camera images alike.
"""

from calib.detection.config import DetectorConfig
from calib.detection.detector import detect_leds
from calib.detection.noise import NoiseModel, estimate_noise
from calib.detection.results import (
    DetectionFailure,
    LedDetection,
    LedDetections,
    RejectedCandidate,
    RejectReason,
)
from calib.detection.sequence import SwitchingSequence

__all__ = [
    "DetectionFailure",
    "DetectorConfig",
    "LedDetection",
    "LedDetections",
    "NoiseModel",
    "RejectReason",
    "RejectedCandidate",
    "SwitchingSequence",
    "detect_leds",
    "estimate_noise",
]
