"""The check's data, gathered from the records the campaign writes as it goes.

A :class:`PointGatherer` stands between the campaign and its recorder: every record passes
on unchanged, and each data point (``/campaign/point``) is kept with what the check needs
beside it: the detector's pixel noise of its LEDs (from the LED observation it was made
of) and the parent's pose and covariance it was measured from (the latest
``/campaign/parent_fix``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from twin.campaign.records import PARENT_FIX, POINT, DataPoint, ParentFix
from twin.hal.readings import LedObservation
from twin.hal.recording import Recorder

LED_TOPIC_PREFIX, LED_TOPIC_SUFFIX = "/camera/", "/leds"
"""Topics of the LED observations (``/camera/NAME/leds``, :mod:`twin.hal.recording`)."""


@dataclass(frozen=True)
class CheckPoint:
    """One stop of the child in a camera's view, as the check uses it.

    Attributes:
        point: the campaign's data point: (n, 3) LED positions in W, m, (n, 2) pixels, px,
            and the (3n, 3n) covariance of the LED positions without the parent's pose
            error, m^2.
        sigma_px: (n,) the detector's standard deviation of each pixel coordinate, px.
        parent: the parent's pose estimate the LEDs were measured from: yaw, rad,
            translation (3,) m in W, and the (4, 4) covariance of (yaw, x, y, z).
    """

    point: DataPoint
    sigma_px: NDArray[np.float64]
    parent: ParentFix


class PointGatherer:
    """A recorder that passes every record on to ``inner`` and keeps each camera's data
    points as :class:`CheckPoint` (:attr:`points`, by camera, in order).

    Args:
        inner: where the records go on to (None: nowhere).
    """

    def __init__(self, inner: Recorder | None = None) -> None:
        self.inner = inner
        self.points: dict[str, list[CheckPoint]] = {}
        self._parent: ParentFix | None = None
        self._seen: dict[str, LedObservation] = {}

    def record(self, topic: str, record: object, timestamp: float) -> None:
        """Pass the record on; keep what the check needs."""
        if self.inner is not None:
            self.inner.record(topic, record, timestamp)
        if topic == PARENT_FIX and isinstance(record, ParentFix):
            self._parent = record
        elif isinstance(record, LedObservation) and _is_led_topic(topic):
            self._seen[record.camera] = record
        elif topic == POINT and isinstance(record, DataPoint):
            self.points.setdefault(record.camera, []).append(self._check_point(record))

    def _check_point(self, point: DataPoint) -> CheckPoint:
        """The point with the noise of its LEDs and the parent's pose it was measured
        from.

        Raises:
            RuntimeError: the point came without its observation or a parent fix (the
                campaign records both before it), or does not match the observation.
        """
        seen = self._seen.get(point.camera)
        if seen is None or self._parent is None:
            raise RuntimeError(
                f"a data point of {point.camera} came before its LED observation or the "
                "parent's first fix: the rig's LED sensors must be recorded to this gatherer"
            )
        found = seen.found
        pixels = np.asarray(point.pixels, dtype=float).reshape(-1, 2)
        if int(found.sum()) != len(pixels) or not np.array_equal(seen.pixels[found], pixels):
            raise RuntimeError(
                f"a data point of {point.camera} does not match the camera's last LED observation"
            )
        return CheckPoint(point, np.asarray(seen.sigma_px[found], dtype=float), self._parent)


def _is_led_topic(topic: str) -> bool:
    return topic.startswith(LED_TOPIC_PREFIX) and topic.endswith(LED_TOPIC_SUFFIX)
