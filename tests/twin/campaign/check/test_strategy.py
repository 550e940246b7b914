"""Where the check takes each camera's data: from the first station if it sees the camera,
else from the camera's first visit station, in the plan's order; travel and stops are the
wrapped strategy's."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from numpy.testing import assert_allclose

from twin.campaign.check.strategy import CheckStrategy
from twin.campaign.strategy import StopPlan, Strategy


class _Inner(Strategy):
    name = "inner"

    def __init__(self) -> None:
        self.started = False
        self.asked: list[tuple] = []

    def start(self, view):
        self.started = True

    def reference_cameras(self, view):
        return ["a", "c"]

    def next_visit(self, view):
        raise AssertionError("the check plans its own visits")

    def next_leg(self, view, goal):
        self.asked.append(("leg", goal.camera))
        return None

    def data_stops(self, view, camera, dataset, points):
        self.asked.append(("stops", camera, points))
        return StopPlan("child1", [])


def _view():
    visit = lambda camera, x: SimpleNamespace(camera=camera, station=(x, 0.0), yaw_deg=90.0)  # noqa: E731
    visits = [visit("b", 1.0), visit("a", 2.0), visit("d", 3.0), visit("b", 4.0), visit("e", 5.0)]
    return SimpleNamespace(scenario=SimpleNamespace(calibration=SimpleNamespace(visits=visits)))


def test_the_check_plans_each_camera_once():
    inner, view = _Inner(), _view()
    plan = CheckStrategy(inner, ["e", "a", "b", "f"])
    plan.start(view)
    assert inner.started
    assert plan.reference_cameras(view) == ["a"]
    first = plan.next_visit(view)
    second = plan.next_visit(view)
    assert plan.next_visit(view) is None
    # In the plan's order (b's first visit comes before e's), each from its first station.
    assert (first.camera, second.camera) == ("b", "e")
    assert_allclose(first.station, [1.0, 0.0])
    assert first.yaw == np.radians(90.0)
    assert plan.no_station == ["f"]
    plan.next_leg(view, first)
    plan.data_stops(view, "b", "visit", 20)
    assert inner.asked == [("leg", "b"), ("stops", "b", 20)]
