"""A control point measured again after a long travel: the gate that rejects another prism
widens with the parent's own uncertainty, so that the drift the loop is there to close is
not what rejects it."""

from __future__ import annotations

import numpy as np
import pytest

from twin.campaign.control_points import GATE_M, GATE_SIGMAS, ControlPoints, later_gate
from twin.campaign.journal import Journal
from twin.hal import Clock, TotalStation, TotalStationMeasurement
from twin.hal.readings import TiltReading
from twin.instruments.polar import cartesian2polar
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec
from twin.localization.planar import world2level
from twin.localization.pose import ParentPose
from twin.scenario.schema import ControlPoint

POINT = np.array([2.0, 1.0, 0.2])
"""Where the control point was first measured, W, m."""


class _Clock(Clock):
    def now(self) -> float:
        return 0.0

    def sleep(self, seconds: float) -> None:
        pass

    def close(self) -> None:
        pass


class _Station(TotalStation):
    """Answers every aim with the prism truly at ``prism_level`` (the levelled frame)."""

    spec = TotalStationSpec()
    inclinometer = InclinometerSpec()

    def __init__(self, prism_level: np.ndarray) -> None:
        self.prism_level = prism_level

    def point(self, target_level) -> None:
        pass

    def measure(self) -> TotalStationMeasurement:
        return TotalStationMeasurement.from_polar(cartesian2polar(self.prism_level), 0.0)

    def read_inclination(self) -> TiltReading:
        return TiltReading(0.0, 0.0, 0.0)

    def close(self) -> None:
        pass


class _Records:
    def __init__(self) -> None:
        self.topics: list[str] = []

    def record(self, topic: str, record: object, timestamp: float) -> None:
        self.topics.append(topic)


def _parent(std: float) -> ParentPose:
    return ParentPose(0.3, np.zeros(3), np.diag([1e-8, std**2, std**2, 1e-8]))


def test_the_gate_is_the_fixed_one_until_the_parent_is_uncertain():
    assert later_gate(_parent(0.0)) == GATE_M
    assert later_gate(_parent(0.9 * GATE_M / GATE_SIGMAS)) == GATE_M
    assert later_gate(_parent(0.2)) == pytest.approx(GATE_SIGMAS * 0.2)


@pytest.mark.parametrize(("std", "accepted"), [(0.02, False), (0.2, True)])
def test_a_drifted_measurement_is_accepted_within_the_parents_uncertainty(std, accepted):
    # The parent believes it stands at W's origin; the point answers 0.3 m from where it
    # was first measured (the group's drift after a long travel, or another prism).
    parent = _parent(std)
    shifted = POINT + np.array([0.3, 0.0, 0.0])
    station = _Station(world2level(shifted, parent.yaw, parent.translation))
    records = _Records()
    journal = Journal(records, _Clock())
    point = ControlPoint(name="start_prism", position=tuple(POINT), surveyed=True)
    points = ControlPoints(station, journal, [point], lock_retries=0)
    points.sight(parent, "parent")
    assert points.sightings["start_prism"] == (1 if accepted else 0)
    assert journal.outcome.failures["control_point_mismatch"] == (0 if accepted else 1)
    assert ("/campaign/control_sighting" in records.topics) == accepted
