"""A run's data points again from its log, with what the check weighs them by: each point's
pixel noise (from its LED observation) and the parent's pose it was measured from.

The log's records are fed, in order, to the check's
:class:`twin.campaign.check.gathering.PointGatherer`, as the campaign fed them when it
ran; :func:`calibration_covariances` then gives each calibration's covariance from its
visit's points (:func:`twin.campaign.check.calibration.calibration_covariance`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from calib.camera import TsaiCamera
from calib.io.camera_files import camera_from_dict
from twin.campaign.check.calibration import calibration_covariance
from twin.campaign.check.gathering import CheckPoint, PointGatherer
from twin.campaign.records import CALIBRATION, PARENT_FIX, POINT, DataPoint, ParentFix
from twin.record import LogMessage, decode
from twin.record.codec import TYPE_KEY

_TUPLES = ("children",)
"""Fields of the rebuilt records that are tuples, not arrays."""


def _rebuilt(cls: type, data: dict[str, Any]) -> Any:
    """A record of ``cls`` (a frozen dataclass of arrays and plain values) from its logged
    form: lists become float arrays (a None, a NaN or infinity written as null, NaN)."""
    values = {}
    for f in dataclasses.fields(cls):
        if f.name not in data:
            continue
        v = data[f.name]
        if isinstance(v, list):
            v = tuple(v) if f.name in _TUPLES else np.asarray(v, dtype=float)
        values[f.name] = v
    return cls(**values)


def gathered(messages: Iterable[LogMessage]) -> PointGatherer:
    """Every data point of a log as the check gathers it (by camera, in order)."""
    gatherer = PointGatherer()
    for m in messages:
        data = m.data
        if m.topic == PARENT_FIX:
            gatherer.record(m.topic, _rebuilt(ParentFix, data), m.timestamp)
        elif m.topic == POINT:
            gatherer.record(m.topic, _rebuilt(DataPoint, data), m.timestamp)
        elif isinstance(data, dict) and data.get(TYPE_KEY) == "LedObservation":
            gatherer.record(m.topic, decode(data), m.timestamp)
    return gatherer


def visit_points(gatherer: PointGatherer, camera: str, visit: int, leds: int) -> list[CheckPoint]:
    """The points of ``camera``'s visit ``visit`` that its calibration used: the first
    ones, up to ``leds`` LED points (the last one cut short where the set ended inside
    it)."""
    out: list[CheckPoint] = []
    taken = 0
    for p in gatherer.points.get(camera, []):
        if p.point.dataset != "visit" or p.point.visit != visit or taken >= leds:
            continue
        k = len(p.point.pixels)
        if taken + k > leds:
            p = _first_leds(p, leds - taken)
            k = leds - taken
        out.append(p)
        taken += k
    return out


def _first_leds(p: CheckPoint, n: int) -> CheckPoint:
    """The point with only its first ``n`` LEDs."""
    rows = slice(0, 3 * n)
    point = dataclasses.replace(
        p.point,
        leds_world=p.point.leds_world[:n],
        pixels=p.point.pixels[:n],
        leds_covariance=p.point.leds_covariance[rows, rows]
        if np.size(p.point.leds_covariance)
        else p.point.leds_covariance,
        survey_loading=p.point.survey_loading[rows]
        if np.size(p.point.survey_loading)
        else p.point.survey_loading,
    )
    return CheckPoint(point, p.sigma_px[:n], p.parent)


def calibration_covariances(
    messages: list[LogMessage],
) -> dict[tuple[str, int], NDArray[np.float64]]:
    """Each Tsai calibration's (11, 11) covariance
    (:data:`calib.camera_covariance.CAMERA_PARAMETERS`) by (camera, visit), from the
    points of its visit in the log. A calibration whose points the log lacks (or not all
    of them, or in another model) gets none."""
    gatherer = gathered(messages)
    out: dict[tuple[str, int], NDArray[np.float64]] = {}
    for m in messages:
        if m.topic != CALIBRATION or m.data.get("camera_model", {}).get("model") != "tsai":
            continue
        camera, visit, n = m.data["camera"], int(m.data["visit"]), int(m.data["points"])
        points = visit_points(gatherer, camera, visit, n)
        if sum(len(p.point.pixels) for p in points) != n:
            continue
        model = camera_from_dict(m.data["camera_model"], "calibration")
        assert isinstance(model, TsaiCamera)
        try:
            out[camera, visit] = calibration_covariance(model, points)
        except (ValueError, np.linalg.LinAlgError):
            continue
    return out
