"""Cross-checks between a scenario's sections, each problem a :class:`ScenarioIssue`.

The loader runs :func:`check_scenario` once every section has passed its own checks.
"""

from __future__ import annotations

from twin.scenario.cross_checks.calibration_plan import (
    check_campaign,
    check_visits,
    scenario_station_visibility,
)
from twin.scenario.cross_checks.floor import MIN_OBSTACLE_HEIGHT, check_obstacles, check_patches
from twin.scenario.cross_checks.names import RESERVED_NAMES, RESERVED_PREFIXES, check_names
from twin.scenario.cross_checks.placement import (
    PARENT_CLEARANCE,
    START_GAP,
    check_cameras,
    check_control_points,
    check_moved_cameras,
    check_robots,
    check_world_frame,
)
from twin.scenario.cross_checks.routes import (
    PERSON_CLEARANCE,
    ROUTE_START,
    check_people,
    check_route,
)
from twin.scenario.errors import ScenarioIssue
from twin.scenario.schema import Scenario

__all__ = [
    "MIN_OBSTACLE_HEIGHT",
    "PARENT_CLEARANCE",
    "PERSON_CLEARANCE",
    "RESERVED_NAMES",
    "RESERVED_PREFIXES",
    "ROUTE_START",
    "START_GAP",
    "check_scenario",
    "scenario_station_visibility",
]


def check_scenario(sc: Scenario) -> list[ScenarioIssue]:
    """Every cross-section problem of ``sc`` (empty when it is consistent)."""
    issues: list[ScenarioIssue] = []
    issues += check_names(sc)
    issues += check_world_frame(sc)
    issues += check_cameras(sc)
    issues += check_robots(sc)
    issues += check_obstacles(sc)
    issues += check_patches(sc)
    issues += check_route(sc)
    issues += check_visits(sc)
    issues += check_people(sc)
    issues += check_campaign(sc)
    issues += check_moved_cameras(sc)
    issues += check_control_points(sc)
    return issues
