"""The smoke room with a loop, for the global adjustment's tests."""

from __future__ import annotations

from pathlib import Path

from twin.scenario import Scenario, load_scenario
from twin.scenario.schema import CalibrationVisit, ControlPoint, Route

ROOT = Path(__file__).resolve().parents[3]


def loop_scenario() -> Scenario:
    """The smoke room with a loop: camera 1 at the start and at the end, back to the start,
    one prism near the start and one mark the route never comes near."""
    sc = load_scenario(ROOT / "scenarios" / "smoke.toml")
    return sc.model_copy(
        update={
            "route": Route(
                waypoints=(
                    (0.0, 0.0),
                    (4.0, 0.0),
                    (4.0, 2.4),
                    (-1.0, 2.4),
                    (-1.0, 0.0),
                    (0.0, 0.0),
                ),
                return_to_start=True,
            ),
            "calibration": sc.calibration.model_copy(
                update={
                    "visits": (
                        CalibrationVisit(camera="cam1", station=(0.5, 0.0)),
                        CalibrationVisit(camera="cam1", station=(0.5, 2.4), yaw_deg=180.0),
                    )
                }
            ),
            "control_points": (
                ControlPoint(name="start_prism", position=(-1.5, -1.5, 0.0), sight_radius_m=3.0),
                ControlPoint(name="far_mark", position=(7.5, 2.5, 0.0), sight_radius_m=0.5),
            ),
        }
    )
