"""Each data point is kept with its LEDs' pixel noise and the parent's fix it was measured
from; every record passes on."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from twin.campaign.check.gathering import PointGatherer
from twin.campaign.records import PARENT_FIX, POINT, DataPoint, ParentFix
from twin.hal.readings import LedObservation


class _List:
    def __init__(self) -> None:
        self.records: list[tuple[str, object]] = []

    def record(self, topic: str, record: object, timestamp: float) -> None:
        self.records.append((topic, record))


def _observation(pixels, sigma) -> LedObservation:
    found = np.all(np.isfinite(pixels), axis=1)
    failures = tuple(None if f else "occluded" for f in found)
    return LedObservation("cam1", "child1", 1.0, np.asarray(pixels), np.asarray(sigma), failures)


def _point(pixels) -> DataPoint:
    n = len(pixels)
    leds = np.arange(3 * n, dtype=float).reshape(n, 3)
    return DataPoint(1.0, "reference", "cam1", 0, "child1", leds, np.asarray(pixels),
                     np.zeros(2), np.eye(3 * n))  # fmt: skip


FIX = ParentFix(0.5, 0, 0.1, np.array([1.0, 2.0, 0.0]), np.eye(4) * 1e-8, 0.0)


def test_a_point_is_kept_with_its_noise_and_its_fix():
    inner = _List()
    g = PointGatherer(inner)
    pixels = np.array([[10.0, 20.0], [np.nan, np.nan], [30.0, 40.0], [50.0, 60.0]])
    g.record(PARENT_FIX, FIX, 0.5)
    g.record("/camera/cam1/leds", _observation(pixels, [0.01, np.nan, 0.02, 0.03]), 1.0)
    g.record(POINT, _point(pixels[[0, 2, 3]]), 1.0)
    (kept,) = g.points["cam1"]
    assert_allclose(kept.sigma_px, [0.01, 0.02, 0.03])
    assert kept.parent is FIX
    assert [t for t, _ in inner.records] == [PARENT_FIX, "/camera/cam1/leds", POINT]


def test_a_point_without_its_observation_or_not_matching_it_is_an_error():
    g = PointGatherer()
    pixels = np.array([[10.0, 20.0], [30.0, 40.0]])
    g.record(PARENT_FIX, FIX, 0.5)
    with pytest.raises(RuntimeError, match="before its LED observation"):
        g.record(POINT, _point(pixels), 1.0)
    g.record("/camera/cam1/leds", _observation(pixels, [0.01, 0.02]), 1.0)
    with pytest.raises(RuntimeError, match="does not match"):
        g.record(POINT, _point(pixels + 1.0), 1.0)
