"""Every scenario file loads into frozen, typed objects with the numbers it documents."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pydantic
import pytest
import yaml

from twin.instruments.marker import MarkerAssembly
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec
from twin.scenario import Scenario, load_scenario
from twin.scenario.geometry import floor_view_corners

from .helpers import SCENARIOS, variant

ALL = sorted(p.stem for p in SCENARIOS.glob("*.toml"))


def test_the_three_scenarios_exist():
    assert {"paper_hall", "corridor", "smoke"} <= set(ALL)


@pytest.mark.parametrize("name", ALL)
def test_every_scenario_loads(name):
    sc = load_scenario(SCENARIOS / f"{name}.toml")
    assert isinstance(sc, Scenario)
    assert sc.name == name
    assert sc.source.endswith(f"{name}.toml")
    assert len(sc.robots.children) >= 1
    assert sc.route.length > 0


def test_scenario_is_frozen():
    sc = load_scenario(SCENARIOS / "smoke.toml")
    with pytest.raises(pydantic.ValidationError):
        sc.seed = 3
    with pytest.raises(pydantic.ValidationError):
        sc.cameras[0].f = 1.0
    assert isinstance(sc.cameras, tuple)
    assert isinstance(sc.cameras[0].position, tuple)


def test_noise_and_marker_default_to_the_instrument_specs():
    sc = load_scenario(SCENARIOS / "smoke.toml")
    assert sc.noise.total_station.spec() == TotalStationSpec()
    assert sc.noise.inclinometer.spec() == InclinometerSpec()
    default = MarkerAssembly()
    np.testing.assert_array_equal(sc.marker.assembly().cubes_body, default.cubes_body)
    np.testing.assert_array_equal(sc.marker.assembly().leds_body, default.leds_body)


def test_noise_and_marker_can_be_overridden(tmp_path):
    path = variant(
        tmp_path,
        "override",
        [
            (
                "[route]",
                "[noise.total_station]\nangle_sigma = 1e-5\n\n"
                "[marker]\ncubes = [[0.1, 0.0, 1.5], [-0.1, 0.1, 1.5], [-0.1, -0.1, 1.5]]\n\n"
                "[route]",
            )
        ],
    )
    sc = load_scenario(path)
    assert sc.noise.total_station.spec().angle_sigma == 1e-5
    assert sc.noise.total_station.spec().range_min == TotalStationSpec().range_min
    assert sc.marker.assembly().cubes_body[0, 2] == 1.5


def test_paper_hall_matches_the_paper():
    sc = load_scenario(SCENARIOS / "paper_hall.toml")
    assert sc.space.size == (60.0, 15.0, 8.0)
    assert sc.robots.parent.start_xy == (0.0, 0.0)
    assert sc.route.length == pytest.approx(85.0)
    assert sorted(abs(t) for t in sc.route.turns_deg if abs(t) > 1) == [90.0, 90.0]
    assert [v.camera for v in sc.calibration.visits] == ["cam1", "cam2", "cam3", "cam2", "cam1"]
    for cam in sc.cameras:
        # 2.5 m above the floor, looking 20-35 deg down.
        assert cam.position[2] - sc.space.floor_z == pytest.approx(2.5, abs=0.05)
        axis = cam.tsai().optical_axis
        assert 20.0 <= math.degrees(math.asin(-axis[2])) <= 35.0
        assert cam.image_size == (320, 240)
    # Camera 1's view of the floor lies about 3.5-8.5 m in front of it.
    cam1 = sc.camera("cam1").tsai()
    corners = floor_view_corners(cam1, sc.space.floor_z)
    dist = np.linalg.norm(corners - cam1.position[:2], axis=1)
    assert 3.0 < dist.min() < 4.5
    assert 7.5 < dist.max() < 10.0


def test_yaml_scenarios_load_the_same(tmp_path):
    raw = tomllib.loads((SCENARIOS / "smoke.toml").read_text(encoding="utf-8"))
    path = tmp_path / "smoke.yaml"
    path.write_text(yaml.safe_dump(raw), encoding="utf-8")
    from_yaml = load_scenario(path)
    from_toml = load_scenario(SCENARIOS / "smoke.toml")
    assert from_yaml.model_dump(exclude={"source"}) == from_toml.model_dump(exclude={"source"})


@pytest.mark.parametrize("name", ["smoke", "paper_hall"])
def test_a_scenario_pickles_to_an_equal_scenario(name):
    # Monte-Carlo workers (processes, Ray tasks) receive their scenario pickled.
    import pickle

    sc = load_scenario(SCENARIOS / f"{name}.toml")
    back = pickle.loads(pickle.dumps(sc))
    assert back == sc
    assert back.noise.total_station.spec() == sc.noise.total_station.spec()


def test_marker_geometry_noise_defaults_to_none_and_is_bounded(tmp_path):
    sc = load_scenario(SCENARIOS / "smoke.toml")
    assert sc.noise.marker_geometry_m == 0.0
    assert sc.without_noise().noise.marker_geometry_m == 0.0
    with pytest.raises(pydantic.ValidationError, match="marker_geometry_m"):
        sc.model_validate({**sc.model_dump(), "noise": {"marker_geometry_m": -0.001}})
