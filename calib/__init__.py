"""Camera model and calibration: Tsai's model, calibration, metrics and camera files, and
the detection of the robots' LEDs in camera frames (:mod:`calib.detection`).

Pure numpy / scipy / OpenCV; nothing here knows about MuJoCo or the robots.
"""

from calib.camera import TsaiCamera, project_tsai
from calib.checks import DegenerateGeometryWarning, InputWarning
from calib.detection import (
    DetectionFailure,
    DetectorConfig,
    LedDetection,
    LedDetections,
    SwitchingSequence,
    detect_leds,
)
from calib.metrics import Metrics, evaluate
from calib.opencv_calibration import calibrate_opencv
from calib.opencv_camera import OpenCVCamera, tsai2opencv
from calib.paper_units import PaperParameters, from_paper_units, to_paper_units
from calib.result import CalibrationResult
from calib.tsai import calibrate_exterior, calibrate_tsai, predicted_covariance

__all__ = [
    "CalibrationResult",
    "DegenerateGeometryWarning",
    "DetectionFailure",
    "DetectorConfig",
    "InputWarning",
    "LedDetection",
    "LedDetections",
    "Metrics",
    "OpenCVCamera",
    "PaperParameters",
    "SwitchingSequence",
    "TsaiCamera",
    "calibrate_exterior",
    "calibrate_opencv",
    "calibrate_tsai",
    "detect_leds",
    "evaluate",
    "from_paper_units",
    "predicted_covariance",
    "project_tsai",
    "to_paper_units",
    "tsai2opencv",
]
