"""The stations of a site that an episode's moves name: each camera's calibration
stations from the scenario's visits, and the start."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from twin.campaign.plan.route import RoutePath
from twin.scenario.schema import CalibrationVisit, Scenario

START = "start"
"""The name of the first station."""


@dataclass(frozen=True)
class Station:
    """A place the group can travel to: a camera's calibration station, or the start.

    Attributes:
        name: ``<camera>@<n>`` (the camera's n-th station in the scenario's visits), or
            ``start``. camera: the camera calibrated there (None at the start).
        xy: (2,) where the parent stands, m in W. yaw: its heading there, rad.
        arc: the station's arc length on the route, m.
    """

    name: str
    camera: str | None
    xy: NDArray[np.float64]
    yaw: float
    arc: float


def visit_stations(scenario: Scenario, stations: dict[str, Station]) -> list[str]:
    """The station of each of the scenario's visits, in order, by name."""
    return [
        next(n for n, s in stations.items() if is_visits(s, visit))
        for visit in scenario.calibration.visits
    ]


def is_visits(station: Station, visit: CalibrationVisit) -> bool:
    """Whether ``station`` is where the scenario's ``visit`` calibrates."""
    return (
        station.camera == visit.camera
        and np.array_equal(station.xy, np.asarray(visit.station, dtype=float))
        and station.yaw == math.radians(visit.yaw_deg)
    )


def site_stations(scenario: Scenario, path: RoutePath) -> dict[str, Station]:
    """The stations of the scenario's visits, in their order (a station visited twice
    counts once), then the start."""
    stations: dict[str, Station] = {}
    seen: dict[str, int] = {}
    for visit in scenario.calibration.visits:
        if any(is_visits(s, visit) for s in stations.values()):
            continue
        xy = np.asarray(visit.station, dtype=float)
        seen[visit.camera] = seen.get(visit.camera, 0) + 1
        name = f"{visit.camera}@{seen[visit.camera]}"
        stations[name] = Station(
            name, visit.camera, xy, math.radians(visit.yaw_deg), path.project(xy)
        )
    start = scenario.robots.parent
    xy = np.asarray(start.start_xy, dtype=float)
    stations[START] = Station(START, None, xy, math.radians(start.start_yaw_deg), path.project(xy))
    return stations
