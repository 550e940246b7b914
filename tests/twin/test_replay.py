"""``twin replay``: a run's outputs again from its log, the same as the run's; a log cut
short gives what it holds; an OpenCV fit of the same points finds the same camera."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from calib.io.camera_files import load_camera_identity
from twin.campaign.log_results import META
from twin.cli import main
from twin.record import McapRecorder, read_log
from twin.run.replay import replay_log, run_scenario_of
from twin.run.run_cameras import IDENTITY_KEYS as KEYS
from twin.run.runner import check_scenario, run_scenario
from twin.scenario import load_scenario
from twin.scenario.digest import scenario_digest

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
    # Without the reference data set (half the run; the pixel size does not depend on it).
    scenario = tmp_path / "fine_pixels.toml"
    scenario.write_text(
        SMOKE.read_text() + "\n[campaign]\npixel_size_mm = 0.005\nreference_cameras = []\n"
    )
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


# --- the run's scenario: found from the log's record, checked by its digest ---------------


@pytest.fixture(scope="module")
def relative_run(tmp_path_factory) -> Path:
    """A run whose scenario was given by a relative path, from the folder that holds it;
    returns that folder (the run is in run/)."""
    folder = tmp_path_factory.mktemp("relative")
    shutil.copy(SMOKE, folder / "smoke.toml")
    here = Path.cwd()
    os.chdir(folder)
    try:
        run_scenario(Path("smoke.toml"), "run", fidelity="geometric", report=False)
    finally:
        os.chdir(here)
    return folder


def _meta(log: Path) -> dict:
    return next(m.data for m in read_log(log).messages if m.topic == META)


def _replay(argv: list[str], capsys) -> tuple[int, str]:
    code = main(["replay", *argv])
    return code, " ".join(capsys.readouterr().out.split())


def test_the_log_records_the_scenarios_absolute_path_and_digest(relative_run):
    meta = _meta(relative_run / "run" / "log.mcap")
    assert meta["scenario_file"] == "smoke.toml"
    assert meta["scenario_path"] == str(relative_run / "smoke.toml")
    assert meta["scenario_digest"] == scenario_digest(load_scenario(SMOKE))


def test_a_log_is_replayed_from_another_folder(relative_run, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code, said = _replay([str(relative_run / "run" / "log.mcap"), "--out", "r"], capsys)
    assert code == 0, said
    assert "warning" not in said
    assert (tmp_path / "r" / "report.md").is_file()


def test_a_scenario_moved_beside_the_log_is_found(relative_run, tmp_path):
    shutil.copytree(relative_run / "run", tmp_path / "run")
    shutil.copy(SMOKE, tmp_path / "run" / "smoke.toml")
    meta = _meta(tmp_path / "run" / "log.mcap")
    found = run_scenario_of(
        {**meta, "scenario_path": str(tmp_path / "gone.toml")}, None, tmp_path / "run" / "log.mcap"
    )
    assert found.source == str(tmp_path / "run" / "smoke.toml")


def test_a_scenario_not_found_is_named_with_the_ways_on(relative_run, tmp_path, capsys):
    log = tmp_path / "log.mcap"
    meta = {
        **_meta(relative_run / "run" / "log.mcap"),
        "scenario_path": str(tmp_path / "gone.toml"),
    }
    _rewrite(relative_run / "run" / "log.mcap", log, meta)
    code, said = _replay([str(log), "--out", str(tmp_path / "r")], capsys)
    assert code == 2
    assert "its scenario smoke.toml was not found" in said
    assert "--scenario" in said
    assert "--no-report" in said
    assert not (tmp_path / "r").exists()
    code, said = _replay([str(log), "--out", str(tmp_path / "r"), "--no-report"], capsys)
    assert code == 0, said


def test_another_scenario_is_refused_by_digest_unless_forced(relative_run, tmp_path, capsys):
    other = tmp_path / "wider.toml"
    other.write_text(SMOKE.read_text().replace("f = 400.0", "f = 420.0"))
    log = str(relative_run / "run" / "log.mcap")
    out = tmp_path / "r"
    code, said = _replay([log, "--scenario", str(other), "--out", str(out)], capsys)
    assert code == 2
    assert f"the scenario {other} ('smoke', digest {scenario_digest(load_scenario(other))})" in said
    assert (
        f"is not the run's ('smoke' from smoke.toml, digest {_meta(Path(log))['scenario_digest']})"
        in said
    )
    assert "--force" in said
    assert not out.exists()
    # The digest is checked without the report too; --force replays all the same.
    code, said = _replay([log, "--scenario", str(other), "--out", str(out), "--no-report"], capsys)
    assert code == 2
    argv = [log, "--scenario", str(other), "--out", str(out), "--force", "--no-report"]
    code, said = _replay(argv, capsys)
    assert code == 0
    assert "replayed with it all the same (--force)" in said


def test_the_runs_seed_and_noise_are_the_runs_scenario(tmp_path):
    # Without the reference data set (half the run; the log's scenario does not depend on it).
    smoke = tmp_path / "smoke.toml"
    smoke.write_text(SMOKE.read_text() + "\n[campaign]\nreference_cameras = []\n")
    run_scenario(smoke, tmp_path / "run", fidelity="geometric", report=False, seed=7, noise=False)
    meta = _meta(tmp_path / "run" / "log.mcap")
    sc = run_scenario_of(meta, smoke, tmp_path / "run" / "log.mcap")
    assert scenario_digest(sc) == meta["scenario_digest"]
    assert sc.seed == 7


def test_an_older_log_without_digest_is_replayed_with_a_warning(relative_run, tmp_path, capsys):
    log = tmp_path / "old.mcap"
    meta = _meta(relative_run / "run" / "log.mcap")
    old = {k: v for k, v in meta.items() if k not in ("scenario_digest", "scenario_path")}
    _rewrite(relative_run / "run" / "log.mcap", log, old)
    argv = [str(log), "--scenario", str(SMOKE), "--out", str(tmp_path / "r"), "--no-report"]
    code, said = _replay(argv, capsys)
    assert code == 0
    assert "records no scenario digest" in said
    assert f"cannot check that {SMOKE}" in said


def test_a_check_log_is_named_as_such(run, tmp_path, capsys):
    out, _ = run
    check_scenario(SMOKE, out / "cameras", tmp_path / "check", fidelity="geometric", seed=5)
    code, said = _replay(
        [str(tmp_path / "check" / "log.mcap"), "--out", str(tmp_path / "r")], capsys
    )
    assert code == 2
    assert "a `twin check` log; twin replay reads the logs of campaigns" in said
    assert "check.json" in said
    assert not (tmp_path / "r").exists()


def _rewrite(log: Path, to: Path, meta: dict) -> None:
    """``log`` copied to ``to`` with its run record replaced by ``meta``."""
    with McapRecorder(to) as recorder:
        for m in read_log(log).messages:
            recorder.record(m.topic, meta if m.topic == META else m.data, m.timestamp)
