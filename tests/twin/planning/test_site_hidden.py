"""``twin site`` with a camera whose floor view a wall partly hides from every station: the
best station is taken where it still sees enough, and the scenario accepts it; a camera
no station sees enough of is left out by name and the rest is planned."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.twin.planning.test_site import CAMERAS, write_cameras, write_grid
from twin.cli import main
from twin.planning import site as site_module
from twin.planning import site_stations
from twin.run.runner import run_scenario
from twin.scenario import load_scenario
from twin.scenario.cross_checks import scenario_station_visibility

WALL = (6.9, 0.0, 7.1, 6.5)
"""A wall across the middle of cam3's view: a station on either side of it sees about
half of the view (the passage north of it is too narrow for a station)."""

CAM3 = dict(CAMERAS[0], name="cam3", position=[7.0, 7.5, 2.5], view_direction=[0.0, -1.0, -0.8])


def plan(folder: Path) -> tuple[int, Path]:
    """``twin site`` on the room with the wall, cam1 and cam3 (no trial run): exit code and
    the scenario's path."""
    grid = write_grid(folder, [WALL])
    cams = write_cameras(folder, [CAMERAS[0], CAM3])
    out = folder / "hidden.toml"
    return main(["site", str(grid), "--cameras", str(cams), "--out", str(out), "--no-predict"]), out


def test_a_half_hidden_view_is_planned_from_the_best_station_and_calibrates(
    tmp_path, monkeypatch, capsys
):
    # The wall hides half of cam3's view from every station; with the need above that
    # half, the plan takes the best station, says so, and lowers the scenario's fraction.
    for module in (site_module, site_stations):
        monkeypatch.setattr(module, "STATION_NEED", 0.6)
    code, out = plan(tmp_path)
    text = capsys.readouterr().out
    assert code == 0, text
    assert "note: camera 'cam3'" in text
    sc = load_scenario(out)
    assert sc.calibration.min_visible_fraction < 0.6
    seen = {
        v.camera: scenario_station_visibility(sc, v.camera, v.station)
        for v in sc.calibration.visits
    }
    assert 0.25 <= seen["cam3"] < 0.6
    assert all(f >= sc.calibration.min_visible_fraction for f in seen.values())
    results = run_scenario(sc, tmp_path / "run", fidelity="geometric", report=False)
    assert sorted(c["camera"] for c in results["calibrations"]) == ["cam1", "cam3"]
    assert not results["skipped_visits"]
    assert all(c["truth"]["position_error_mm"] < 50.0 for c in results["calibrations"])


def test_a_camera_no_station_sees_enough_of_is_left_out_by_name(tmp_path, monkeypatch, capsys):
    # The least a station may see set above what any sees of cam3 (half): cam3 is named
    # with the best fraction and where, and cam1 is planned (exit 1, the scenario written).
    for module in (site_module, site_stations):
        monkeypatch.setattr(module, "STATION_NEED", 0.7)
        monkeypatch.setattr(module, "STATION_FLOOR", 0.6)
    code, out = plan(tmp_path)
    text = capsys.readouterr().out
    assert code == 1, text
    assert "cam3: no station sees 60 % of its floor view" in text
    sc = load_scenario(out)
    assert [v.camera for v in sc.calibration.visits] == ["cam1"]
    assert [c.name for c in sc.cameras] == ["cam1"]


@pytest.mark.parametrize(("partial", "expected"), [({}, 0.5), ({"a": 0.437, "b": 0.9}, 0.42)])
def test_the_scenarios_fraction_follows_the_least_station(partial, expected):
    assert site_module._min_visible(partial) == pytest.approx(expected)
