"""What the covariance propagation predicts for a run, read from its log.

The campaign records the parent's pose covariance at every CPS fix (``ParentFix``, from
:class:`twin.localization.sequence.CpsSequence`) and each calibration's parameter standard
deviations (Tsai's least squares). Two parts make a calibrated camera's world-frame error:

- the frame transfer: the data of a station are measured from the parent's pose there,
  so an error ``(d_yaw, d_t)`` of that pose moves the whole calibration rigidly, the
  camera's centre ``c`` by ``d_t + d_yaw * z x (c - t)``;
- the calibration itself: the spread of the camera's centre from the pixel noise of the
  station's own data (Tsai's covariance, which treats the LED positions as exact, at the
  detector's pixel noise: :func:`calib.covariance.own_position_variance`) and from the
  errors of those LED positions. The LEDs of one stop are placed with their marker's
  measured pose, so they share its error (``DataPoint.leds_covariance``, one block a
  stop): it does not average down over the points as independent errors would
  (:func:`calib.point_errors.position_covariance_from_blocks`).

The prediction is first order and treats the parts as independent.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.camera import TsaiCamera, TsaiCameras
from calib.covariance import own_position_variance
from calib.io.camera_files import camera_from_dict
from calib.point_errors import position_covariance_from_blocks
from twin.campaign.records import CALIBRATION, PARENT_FIX, POINT
from twin.instruments.marker_pose import survey_layout
from twin.truth import TRUTH_INSTRUMENT, instrument_truth


def camera_position_covariance(
    parent_covariance: ArrayLike, parent_translation: ArrayLike, camera_position: ArrayLike
) -> NDArray[np.float64]:
    """Covariance of a camera's world position from the parent pose it was calibrated from.

    Args:
        parent_covariance: (4, 4) covariance of the parent's (yaw, x, y, z), rad and m.
        parent_translation: (3,) the instrument's centre t in W, m.
        camera_position: (3,) the camera's centre c in W, m.

    Returns:
        (3, 3) covariance of the camera's centre, m^2: ``J P J^T`` with
        ``J = [z x (c - t), I3]``.
    """
    p = np.asarray(parent_covariance, dtype=float).reshape(4, 4)
    lever = np.asarray(camera_position, dtype=float) - np.asarray(parent_translation, float)
    jac = np.zeros((3, 4))
    jac[:, 0] = (-lever[1], lever[0], 0.0)
    jac[:, 1:] = np.eye(3)
    return jac @ p @ jac.T


@dataclass(frozen=True)
class CalibrationPrediction:
    """The predicted world-frame position error of one calibration.

    Attributes:
        camera, visit: which calibration.
        transfer_rms_m: RMS 3D error from the parent's pose at the station, m.
        calibration_rms_m: RMS 3D error of the calibration from its own data (pixel
            noise and the points' errors), m.
    """

    camera: str
    visit: int
    transfer_rms_m: float
    calibration_rms_m: float

    @property
    def rms_m(self) -> float:
        """Predicted RMS 3D position error, both parts together, m."""
        return float(np.hypot(self.transfer_rms_m, self.calibration_rms_m))


@dataclass(frozen=True)
class ParentFinal:
    """The parent's last CPS fix against the truth.

    Attributes:
        error_m: (3,) estimated minus true instrument centre, m (NaN without the truth).
        covariance_m2: (3, 3) predicted covariance of the centre, m^2.
        distance_travelled_m: the parent's travel at that fix, m.
    """

    error_m: NDArray[np.float64]
    covariance_m2: NDArray[np.float64]
    distance_travelled_m: float


def points_variance(model: dict[str, Any], stops: Sequence[dict[str, Any]], n: int) -> float:
    """Variance (trace, m^2) of a calibrated camera's centre from the errors of the first
    ``n`` LED points of its data (``DataPoint`` records, one a stop), at the camera;
    0 where the records hold no covariance (logs written before they did)."""
    blocks = [np.asarray(s.get("leds_covariance", []), dtype=float) for s in stops]
    if n < 1 or not blocks or any(b.size == 0 for b in blocks):
        return 0.0
    points = np.concatenate([np.asarray(s["leds_world"], dtype=float) for s in stops])[:n]
    camera = camera_from_dict(model, "calibration record")
    assert isinstance(camera, TsaiCamera)
    cameras = TsaiCameras.from_cameras([camera])
    # Each block padded to the largest (stops with fewer LEDs: campaign.data_stops =
    # "accuracy"), the points' coordinates placed at the start of their stop's block.
    k = max(len(b) for b in blocks)
    padded = np.zeros((len(blocks), k, k))
    columns = []
    for s, b in enumerate(blocks):
        padded[s, : len(b), : len(b)] = b
        columns.append(s * k + np.arange(len(b)))
    cols = np.concatenate(columns)[: 3 * len(points)]
    shared = survey_layout(
        [s.get("child", "") for s in stops],
        [np.asarray(s.get("survey_loading", []), dtype=float) for s in stops],
        k,
    )
    cov = position_covariance_from_blocks(cameras, points[None], padded[None], cols[None], shared)
    return float(np.trace(cov[0]))


def predictions_from_log(
    messages: Iterable[Any], pixel_noise_px: float | Mapping[str, float] | None = None
) -> tuple[list[CalibrationPrediction], ParentFinal | None]:
    """The predicted errors of every calibration of a run, and its parent's last fix.

    Args:
        messages: the log's messages in file order (``LogContents.messages``).
        pixel_noise_px: the LED detector's pixel noise, px
            (:func:`calib.covariance.own_position_variance`), one for every camera or
            each camera's by name.
    """
    fix: dict[str, Any] | None = None
    truth: list[dict[str, Any]] = []
    out: list[CalibrationPrediction] = []
    stops: dict[tuple[str, int], list[dict[str, Any]]] = {}
    for m in messages:
        if m.topic == PARENT_FIX:
            fix = m.data
        elif m.topic == TRUTH_INSTRUMENT:
            truth.append(m.data)
        elif m.topic == POINT and m.data["dataset"] == "visit":
            stops.setdefault((m.data["camera"], int(m.data["visit"])), []).append(m.data)
        elif m.topic == CALIBRATION and fix is not None:
            rec = m.data
            position = np.asarray(rec["camera_model"]["position_m"], dtype=float)
            cov = camera_position_covariance(fix["covariance"], fix["translation"], position)
            std = [float(rec["std"].get(k, 0.0)) for k in ("x", "y", "z")]
            data = stops.get((rec["camera"], int(rec["visit"])), [])
            shared = points_variance(rec["camera_model"], data, int(rec["points"]))
            pixel = (
                pixel_noise_px.get(rec["camera"])
                if isinstance(pixel_noise_px, Mapping)
                else pixel_noise_px
            )
            own = float(own_position_variance(std, rec["sigma_px"], pixel, shared))
            out.append(
                CalibrationPrediction(
                    rec["camera"], int(rec["visit"]), float(np.sqrt(np.trace(cov))), own**0.5
                )
            )
    if fix is None:
        return out, None
    est = np.asarray(fix["translation"], dtype=float)
    (true,) = instrument_truth(truth, [fix["timestamp"]])
    final = ParentFinal(
        error_m=est - true if true is not None else np.full(3, np.nan),
        covariance_m2=np.asarray(fix["covariance"], dtype=float)[1:, 1:],
        distance_travelled_m=float(fix["distance_travelled"]),
    )
    return out, final
