"""A scenario with values changed by key: set, checked, and refused by name."""

from __future__ import annotations

from pathlib import Path

import pytest

from twin.scenario import ScenarioError, load_scenario
from twin.scenario.overrides import with_values

SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"


@pytest.fixture(scope="module")
def hall_scenario():
    return load_scenario(SCENARIOS / "paper_hall.toml")


def test_values_are_set_by_dotted_key_and_validated(hall_scenario):
    sc = with_values(
        hall_scenario,
        {"noise.led_centroid_px": 0.4, "noise.total_station.pointing_sigma": 2e-3},
    )
    assert sc.noise.led_centroid_px == 0.4
    assert sc.noise.total_station.pointing_sigma == 2e-3
    assert sc.noise.total_station.angle_sigma == hall_scenario.noise.total_station.angle_sigma
    with pytest.raises(KeyError, match=r"noise\.no_such_key"):
        with_values(hall_scenario, {"noise.no_such_key": 1.0})
    sc = with_values(hall_scenario, {"campaign.child_creep_m": 1e-3})
    assert sc.campaign.child_creep_m == 1e-3
    with pytest.raises(KeyError, match=r"campaign\.nothing"):
        with_values(hall_scenario, {"campaign.nothing.deeper": 1.0})
    with pytest.raises(ValueError, match="led_centroid_px"):
        with_values(hall_scenario, {"noise.led_centroid_px": -1.0})
    # Integer keys keep their type; the cross-checks between sections run as for a file.
    assert with_values(hall_scenario, {"campaign.min_points": 30}).campaign.min_points == 30
    with pytest.raises(ScenarioError, match=r"calibration\.visits\[0\]\.station"):
        with_values(hall_scenario, {"noise.total_station.range_max": 5.0})
    assert with_values(hall_scenario, {}) == hall_scenario
