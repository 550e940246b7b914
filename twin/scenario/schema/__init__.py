"""The scenario's schema: frozen, typed pydantic models, one module per section of the file.

Every model is re-exported here, so ``from twin.scenario.schema import Scenario`` is the way in.
"""

from twin.scenario.schema.cameras import MAX_IMAGE_PX, MAX_RENDER_PX, CameraConfig, SensorConfig
from twin.scenario.schema.campaign_settings import (
    CampaignSettings,
    ControlPoint,
    FormationSettings,
    StrategyName,
)
from twin.scenario.schema.faults import Faults, MovedCamera
from twin.scenario.schema.fleet import MarkerConfig, RobotConfig, Robots
from twin.scenario.schema.frozen import Frozen, Name
from twin.scenario.schema.instrument_noise import (
    InclinometerConfig,
    Noise,
    OdometryConfig,
    StoppingConfig,
    TotalStationConfig,
)
from twin.scenario.schema.paths import Person, Route, Waypoints, polyline_length
from twin.scenario.schema.scenario import Scenario, SimConfig, SiteInfo
from twin.scenario.schema.space import FloorPatch, Lighting, Obstacle, Space, SpaceMap
from twin.scenario.schema.visits import Calibration, CalibrationVisit

__all__ = [
    "MAX_IMAGE_PX",
    "MAX_RENDER_PX",
    "Calibration",
    "CalibrationVisit",
    "CameraConfig",
    "CampaignSettings",
    "ControlPoint",
    "Faults",
    "FloorPatch",
    "FormationSettings",
    "Frozen",
    "InclinometerConfig",
    "Lighting",
    "MarkerConfig",
    "MovedCamera",
    "Name",
    "Noise",
    "Obstacle",
    "OdometryConfig",
    "Person",
    "RobotConfig",
    "Robots",
    "Route",
    "Scenario",
    "SensorConfig",
    "SimConfig",
    "SiteInfo",
    "Space",
    "SpaceMap",
    "StoppingConfig",
    "StrategyName",
    "TotalStationConfig",
    "Waypoints",
    "polyline_length",
]
