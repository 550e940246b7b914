"""Where the check takes each camera's data: the campaign's decisions, narrowed.

A camera that the parent's first station sees (the cameras whose reference data sets a
campaign would take there) is checked from there, in W itself; any other is checked from
the scenario's first visit station for it, reached by the campaign's CPS travel. The legs
and the child's stops are the wrapped strategy's own (the paper's by default), asked for
a handful of points instead of a calibration's.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from twin.campaign.strategy import (
    CampaignView,
    Leg,
    NoLeg,
    Return,
    StopPlan,
    Strategy,
    Visit,
)


class CheckStrategy(Strategy):
    """The check's decisions: each camera of ``cameras`` once, from the first station if it
    sees the camera, else from the camera's first visit station; travel and data stops as
    ``inner`` decides them.

    Args:
        inner: the campaign's strategy (its legs and data stops are used).
        cameras: the cameras to check, by name.

    Attributes:
        from_first: after :meth:`start`, the cameras checked from the first station.
        visits: the visits planned for the others.
        no_station: cameras that neither the first station sees nor any visit names.
    """

    name = "check"

    def __init__(self, inner: Strategy, cameras: Sequence[str]) -> None:
        self.inner = inner
        self.cameras = list(cameras)
        self.from_first: list[str] = []
        self.visits: list[Visit] = []
        self.no_station: list[str] = []
        self._next = 0

    def start(self, view: CampaignView) -> None:
        self.inner.start(view)
        seen = set(self.inner.reference_cameras(view))
        self.from_first = [c for c in self.cameras if c in seen]
        first_visits = _first_visits(view, [c for c in self.cameras if c not in seen])
        # In the plan's order: the route passes the stations in turn.
        self.visits = [v for _, v in sorted(first_visits.values(), key=lambda kv: kv[0])]
        self.no_station = [c for c in self.cameras if c not in seen and c not in first_visits]
        self._next = 0

    def reference_cameras(self, view: CampaignView) -> list[str]:
        return list(self.from_first)

    def next_visit(self, view: CampaignView) -> Visit | Return | None:
        if self._next >= len(self.visits):
            return None
        self._next += 1
        return self.visits[self._next - 1]

    def next_leg(self, view: CampaignView, goal: Visit | Return) -> Leg | NoLeg | None:
        return self.inner.next_leg(view, goal)

    def data_stops(self, view: CampaignView, camera: str, dataset: str, points: int) -> StopPlan:
        return self.inner.data_stops(view, camera, dataset, points)


def _first_visits(view: CampaignView, cameras: Sequence[str]) -> dict[str, tuple[int, Visit]]:
    """Each camera's first visit in the scenario's plan, with its place in the plan."""
    wanted = set(cameras)
    out: dict[str, tuple[int, Visit]] = {}
    for k, v in enumerate(view.scenario.calibration.visits):
        if v.camera in wanted and v.camera not in out:
            station = np.asarray(v.station, dtype=float)
            out[v.camera] = (k, Visit(v.camera, 1, station, math.radians(v.yaw_deg)))
    return out
