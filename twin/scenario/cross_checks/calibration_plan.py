"""The calibration plan against the rest: visits that name a camera and see its view, and
campaign settings that name cameras and fit the robots.

- every calibration visit names a camera, and from its station the total station sees at
  least ``calibration.min_visible_fraction`` of the camera's view of the floor (line of
  sight to the corner cubes of a child standing there, within the instrument's range);
- ``campaign.reference_cameras`` name cameras, ``campaign.min_points`` is at most
  ``campaign.station_points``, and there are two children for CPS.
"""

from __future__ import annotations

import numpy as np

from twin.scenario.cross_checks.placement import PARENT_CLEARANCE, free_issue
from twin.scenario.errors import ScenarioIssue
from twin.scenario.robots import INSTRUMENT_HEIGHT
from twin.scenario.schema import Scenario
from twin.scenario.visibility import station_visibility


def scenario_station_visibility(
    sc: Scenario, camera_name: str, station: tuple[float, float]
) -> float:
    """:func:`twin.scenario.visibility.station_visibility` of a scenario's camera from
    ``station``, with the scenario's own instrument (its range) and marker (the prisms'
    mean height)."""
    ts = sc.noise.total_station
    return station_visibility(
        sc.space,
        sc.camera(camera_name).tsai(),
        station,
        sc.space.floor_z + INSTRUMENT_HEIGHT,
        float(np.mean([c[2] for c in sc.marker.cubes])),
        (ts.range_min, ts.range_max),
    )


def check_visits(sc: Scenario) -> list[ScenarioIssue]:
    """``calibration.visits``: each names a camera, stands on free floor and sees enough of
    the camera's floor view."""
    issues = []
    names = [c.name for c in sc.cameras]
    for i, visit in enumerate(sc.calibration.visits):
        if visit.camera not in names:
            issues.append(
                ScenarioIssue(
                    f"calibration.visits[{i}].camera",
                    "unknown camera",
                    visit.camera,
                    f"one of {', '.join(names)}",
                )
            )
            continue
        key = f"calibration.visits[{i}].station"
        issue = free_issue(sc, key, visit.station, PARENT_CLEARANCE, "the station")
        if issue:
            issues.append(issue)
            continue
        frac = scenario_station_visibility(sc, visit.camera, visit.station)
        need = sc.calibration.min_visible_fraction
        if frac < need:
            issues.append(
                ScenarioIssue(
                    key,
                    f"from this station the total station sees only {100 * frac:.0f} % of "
                    f"the floor seen by camera {visit.camera!r} (the rest is blocked or "
                    "out of range)",
                    list(visit.station),
                    f"a station that sees at least {100 * need:.0f} % of it "
                    "(calibration.min_visible_fraction)",
                )
            )
    return issues


def check_campaign(sc: Scenario) -> list[ScenarioIssue]:
    """``campaign``: reference cameras that exist, a minimum the stations can gather, two
    children for CPS."""
    issues = []
    names = [c.name for c in sc.cameras]
    for i, name in enumerate(sc.campaign.reference_cameras or ()):
        if name not in names:
            issues.append(
                ScenarioIssue(
                    f"campaign.reference_cameras[{i}]",
                    "unknown camera",
                    name,
                    f"one of {', '.join(names)}",
                )
            )
    if sc.campaign.min_points > sc.campaign.station_points:
        issues.append(
            ScenarioIssue(
                "campaign.min_points",
                f"more than the {sc.campaign.station_points} points a station gathers",
                sc.campaign.min_points,
                "at most campaign.station_points",
            )
        )
    if len(sc.robots.children) < 2:
        issues.append(
            ScenarioIssue(
                "robots.children",
                "CPS needs two children (one moves while the other stays)",
                len(sc.robots.children),
                "at least 2 children",
            )
        )
    return issues
