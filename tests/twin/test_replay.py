"""``twin replay``: a run's outputs again from its log, the same as the run's; a log cut
short gives what it holds; an OpenCV fit of the same points finds the same camera."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from calib.io.camera_files import load_camera_identity
from twin.cli import main
from twin.replay import replay_log
from twin.run_cameras import IDENTITY_KEYS as KEYS
from twin.runner import run_scenario

ROOT = Path(__file__).resolve().parents[2]
SMOKE = ROOT / "scenarios" / "smoke.toml"


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("run")
    results = run_scenario(SMOKE, out, fidelity="geometric", report=False, seed=5)
    return out, results


def test_the_replay_of_a_log_gives_the_runs_results(run, tmp_path):
    out, results = run
    again = replay_log(out / "log.mcap", tmp_path / "replay", report=False)
    assert again["calibrations"] == results["calibrations"]
    assert again["failures"] == results["failures"]
    assert again["model"] == "tsai"
    written = json.loads((tmp_path / "replay" / "results.json").read_text())
    assert written["calibrations"] == results["calibrations"]
    names = sorted(p.name for p in (tmp_path / "replay" / "cameras").iterdir())
    assert names == sorted(p.name for p in (out / "cameras").iterdir())
    # The camera files record the run's scenario, as the log holds it.
    replayed = load_camera_identity(tmp_path / "replay" / "cameras" / "cam1_visit1.json", KEYS)
    assert replayed == load_camera_identity(out / "cameras" / "cam1_visit1.json", KEYS)
    assert set(replayed) == set(KEYS)


def test_a_replay_without_report_keeps_the_runs_pixel_size(tmp_path):
    scenario = tmp_path / "fine_pixels.toml"
    scenario.write_text(SMOKE.read_text() + "\n[campaign]\npixel_size_mm = 0.005\n")
    results = run_scenario(scenario, tmp_path / "run", fidelity="geometric", report=False, seed=5)
    assert results["pixel_size_mm"] == 0.005
    again = replay_log(tmp_path / "run" / "log.mcap", tmp_path / "replay", report=False)
    assert again["pixel_size_mm"] == 0.005
    assert again["calibrations"] == results["calibrations"]


def test_an_opencv_fit_of_the_same_points_finds_the_same_camera(run, tmp_path):
    out, results = run
    again = replay_log(out / "log.mcap", tmp_path / "cv", model="opencv", report=False)
    tsai, cv = results["calibrations"][0], again["calibrations"][0]
    assert cv["points"] == tsai["points"]
    assert "fx" in json.dumps(cv["std"])  # OpenCV's parameters
    # Both fits see the same points: their positions agree within a few of their stds.
    sigma_mm = 1e3 * np.linalg.norm([tsai["std"][k] for k in ("x", "y", "z")])
    offset = np.subtract(cv["parameters"]["position_mm"], tsai["parameters"]["position_mm"])
    assert np.linalg.norm(offset) < 5 * sigma_mm + 1.0
    assert cv["truth"]["position_error_mm"] < 5 * sigma_mm + tsai["truth"]["position_error_mm"]


def test_the_command_replays_a_killed_runs_log_with_its_report(run, tmp_path):
    out, _results = run
    log = out / "log.mcap"
    cut = tmp_path / "cut.mcap"
    data = log.read_bytes()
    cut.write_bytes(data[: int(len(data) * 0.95)])  # no footer, no summary: as after a kill
    code = main(["replay", str(cut), "--out", str(tmp_path / "r"), "--scenario", str(SMOKE)])
    assert code in (0, 1)
    again = json.loads((tmp_path / "r" / "results.json").read_text())
    assert not again["complete"]
    assert (tmp_path / "r" / "report.md").is_file()


def test_bad_input_is_named(tmp_path, capsys):
    assert main(["replay", str(tmp_path / "none.mcap")]) == 2
    assert "no such log file" in capsys.readouterr().out
    empty = tmp_path / "empty.mcap"
    shutil.copy(ROOT / "scenarios" / "smoke.toml", empty)
    assert main(["replay", str(empty), "--out", str(tmp_path / "o")]) == 2
