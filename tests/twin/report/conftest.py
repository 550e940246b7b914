"""Fixtures: the paper's hall and hand-made campaign results like the paper's five visits."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.twin.report.figure_checks import saved  # noqa: F401  (a fixture)
from twin.report.reading import planned_visits
from twin.scenario import Scenario, load_scenario
from twin.scenario.geometry import floor_view_corners

REPO = Path(__file__).resolve().parents[3]
SCENARIO_FILE = REPO / "scenarios" / "paper_hall.toml"

# Per visit of paper_hall (cam1, cam2, cam3, cam2, cam1): distance travelled (m), the twin's
# world and local errors (px, mm; None: no reference set), the truth errors.
VISITS: tuple[dict[str, Any], ...] = (
    dict(camera="cam1", visit=1, d=1.0, world=(0.31, 2.21), local=(0.05, 0.41), truth=3.2),
    dict(camera="cam2", visit=1, d=12.5, world=(0.42, 3.62), local=(0.06, 0.52), truth=4.5),
    dict(camera="cam3", visit=1, d=40.0, world=None, local=(0.07, 0.63), truth=9.1),
    dict(camera="cam2", visit=2, d=64.5, world=(0.88, 7.15), local=(0.05, 0.47), truth=14.0),
    dict(camera="cam1", visit=2, d=85.0, world=(1.23, 9.87), local=(0.06, 0.55), truth=18.3),
)
F_OFFSET_PX = 0.44  # the twin's calibrated focal length is the truth plus this


@pytest.fixture(scope="session")
def scenario() -> Scenario:
    return load_scenario(SCENARIO_FILE)


def _calibration(scenario: Scenario, spec: dict[str, Any], rng: np.random.Generator) -> dict:
    cam = next(c for c in scenario.cameras if c.name == spec["camera"])
    tsai = cam.tsai()
    station = dict(planned_visits(scenario))[(spec["camera"], spec["visit"])]
    corners = floor_view_corners(tsai, scenario.space.floor_z)
    weights = rng.dirichlet(np.ones(len(corners)), size=60)
    world = spec["world"]
    return {
        "camera": spec["camera"],
        "visit": spec["visit"],
        "station": list(station),
        "distance_travelled_m": spec["d"],
        "points": 60,
        "parameters": {
            "f_px": tsai.f + F_OFFSET_PX,
            "cx": tsai.cx - 0.2,
            "cy": tsai.cy + 0.3,
            "sx": 1.0001,
            "kappa1_px": tsai.kappa1 * 1.02,
            "kappa1_per_mm2": tsai.kappa1 * 1.02 / 0.0074**2,
            "position_mm": (tsai.position * 1e3 + 1.5).tolist(),
            "rotation_deg": np.degrees(tsai.rotation_rad).tolist(),
        },
        "errors": {
            "world": None
            if world is None
            else {"pixel_mean": world[0], "error_3d_mean_mm": world[1], "points": 70},
            "local": {
                "pixel_mean": spec["local"][0],
                "error_3d_mean_mm": spec["local"][1],
                "points": 60,
            },
        },
        "truth": {"position_error_mm": spec["truth"], "rotation_error_deg": 0.012},
        "residuals_px": rng.normal(0.0, 0.05, size=(60, 2)).tolist(),
        "data_points_xy": (weights @ corners).tolist(),
    }


@pytest.fixture
def results(scenario: Scenario) -> dict[str, Any]:
    """Results of a complete run with the paper's five calibrations."""
    rng = np.random.default_rng(7)
    route = np.asarray(scenario.route.waypoints)
    track = np.vstack([np.linspace(route[i], route[i + 1], 5) for i in range(len(route) - 1)])
    cals = [_calibration(scenario, spec, rng) for spec in VISITS]
    return {
        "scenario": "paper_hall",
        "scenario_file": "scenarios/paper_hall.toml",
        "fidelity": "geometric",
        "seed": 20080922,
        "complete": True,
        "wall_time_s": 123.4,
        "timings_s": {"render": 40.1, "physics": 30.2, "solving": 5.0, "detection": 3.0},
        "reference_sets": [{"camera": "cam1", "points": 70}, {"camera": "cam2", "points": 70}],
        "calibrations": cals,
        "skipped_visits": [],
        "repeatability_mm": {"cam1": [1.2, -0.3, 0.1], "cam2": [0.8, 0.4, -0.2]},
        "parent_final_error_mm": 12.3,
        "parent_track": {
            "estimated": track.tolist(),
            "true": (track + rng.normal(0.0, 0.01, track.shape)).tolist(),
        },
        "failures": {"lost_lock": 2, "leds_not_found": 3, "point_unreachable": 0},
        "events": {"prism_reaimed": 7, "child_turned": 1},
    }


@pytest.fixture
def results_skipped(results: dict[str, Any]) -> dict[str, Any]:
    """A partial run: camera 2's second visit skipped, no repeatability recorded."""
    out = copy.deepcopy(results)
    out["complete"] = False
    out["calibrations"] = [
        c for c in out["calibrations"] if (c["camera"], c["visit"]) != ("cam2", 2)
    ]
    out["skipped_visits"] = [
        {
            "camera": "cam2",
            "visit": 2,
            "station": [16.0, 4.0],
            "reason": "station_unreachable",
            "message": "the parent could not reach (16.0, 4.0) | blocked",
        }
    ]
    del out["repeatability_mm"]
    del out["timings_s"]
    out["parent_track"] = {"estimated": out["parent_track"]["estimated"]}
    return out
