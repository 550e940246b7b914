"""Scenario files: the space, cameras, robots, marker, noise, route and calibration plan.

``load_scenario(path)`` reads a TOML (or YAML) file, validates it and returns a frozen
:class:`Scenario`; a bad file raises :class:`ScenarioError` naming the file, the key, the
value and what was expected. Nothing runs on a scenario that fails validation.
"""

from twin.scenario.errors import ScenarioError, ScenarioIssue
from twin.scenario.loader import load_scenario, scenario_from_dict
from twin.scenario.schema import (
    CalibrationVisit,
    CameraConfig,
    FloorPatch,
    MarkerConfig,
    Obstacle,
    RobotConfig,
    Scenario,
    Space,
)

__all__ = [
    "CalibrationVisit",
    "CameraConfig",
    "FloorPatch",
    "MarkerConfig",
    "Obstacle",
    "RobotConfig",
    "Scenario",
    "ScenarioError",
    "ScenarioIssue",
    "Space",
    "load_scenario",
    "scenario_from_dict",
]
