"""``twin check``: the table, ``check.json`` and the exit codes, and bad input refused
with a named error before anything is written (or the twin loaded)."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from calib.io.camera_files import camera_to_dict, load_camera_identity
from twin.cli import main
from twin.run.run_cameras import IDENTITY_KEYS, camera_identity
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"
CALIBRATION = 'visits = [{ camera = "cam1", station = [0.5, 0.0] }]'
SMOKE_CAMERA = load_scenario(SMOKE).camera("cam1").tsai()


def _variant(tmp_path: Path, name: str, extra: str) -> Path:
    text = SMOKE.read_text(encoding="utf-8")
    path = tmp_path / f"{name}.toml"
    path.write_text(text.replace(CALIBRATION, CALIBRATION + "\n\n" + extra), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def cameras(tmp_path_factory) -> Path:
    """The cameras/ folder of a geometric run of the smoke room."""
    out = tmp_path_factory.mktemp("run") / "run"
    # The paper's stops (4 LEDs each), which the counts below are of.
    args = ["run", str(SMOKE), "--fidelity", "geometric", "--seed", "3", "--no-report"]
    assert main([*args, "--strategy", "paper", "--out", str(out)]) == 0
    return out / "cameras"


def _check(scenario: Path, cameras: Path, out: Path, *extra: str) -> int:
    args = ["check", str(scenario), "--cameras", str(cameras), "--fidelity", "geometric"]
    return main([*args, "--seed", "3", "--strategy", "paper", "--out", str(out), *extra])


def _said(capsys) -> str:
    captured = capsys.readouterr()
    return " ".join((captured.out + captured.err).split())


def test_an_unmoved_camera_exits_with_0(cameras, tmp_path, capsys):
    out = tmp_path / "check"
    assert _check(SMOKE, cameras, out) == 0
    said = _said(capsys)
    assert "unchanged" in said
    assert "false-alarm rate 0.001" in said
    results = json.loads((out / "check.json").read_text())
    entry = results["cameras"]["cam1"]
    for key in ("moved", "shift_mm", "turn_deg", "shift_vector_mm", "turn_vector_deg", "chi2"):
        assert key in entry
    assert entry["moved"] is False
    assert results["stops"] == 5
    assert (out / "log.mcap").exists()
    # The run's camera files record its scenario (run with --seed 3), as the check does.
    run = camera_identity(load_scenario(SMOKE).model_copy(update={"seed": 3}))
    assert load_camera_identity(cameras / "cam1_visit1.json", IDENTITY_KEYS) == run
    assert run["site_digest"] in (cameras / "cam1_visit1.yaml").read_text()
    assert {k: results[k] for k in IDENTITY_KEYS} == run


def test_a_moved_camera_exits_with_1_and_is_reposed(cameras, tmp_path, capsys):
    scenario = _variant(
        tmp_path, "moved", '[[faults.moved_cameras]]\ncamera = "cam1"\nshift = [0.0, 0.02, 0.0]\n'
    )
    out = tmp_path / "check"
    assert _check(scenario, cameras, out, "--stops", "4", "--false-alarm-rate", "1e-4") == 1
    said = _said(capsys)
    assert "moved" in said
    results = json.loads((out / "check.json").read_text())
    entry = results["cameras"]["cam1"]
    assert entry["moved"] is True
    assert entry["points"] == 16
    assert entry["false_alarm_rate"] == 1e-4
    assert entry["shift_mm"] == pytest.approx(20.0, abs=10.0)
    assert entry["reposed"]["model"] == "tsai"
    checked = camera_identity(load_scenario(scenario).model_copy(update={"seed": 3}))
    assert load_camera_identity(out / "cameras" / "cam1_check.json", IDENTITY_KEYS) == checked
    # The re-posed camera is checked next time in place of the calibration.
    again = tmp_path / "again"
    folder = tmp_path / "folder"
    folder.mkdir()
    shutil.copy(cameras / "cam1_visit1.json", folder)
    shutil.copy(out / "cameras" / "cam1_check.json", folder)
    assert _check(scenario, folder, again) == 0
    assert json.loads((again / "check.json").read_text())["cameras"]["cam1"]["calibration"] == (
        "cam1_check.json"
    )


def _refused(capsys, args: list[str], *expected: str) -> None:
    assert main(args) == 2
    said = _said(capsys)
    for text in expected:
        assert text in said, said


def test_a_missing_or_empty_cameras_folder_is_refused(tmp_path, capsys):
    out = tmp_path / "check"
    missing = tmp_path / "nowhere"
    _refused(capsys, ["check", str(SMOKE), "--cameras", str(missing), "--out", str(out)],
             f"--cameras {missing}: no such folder")  # fmt: skip
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "cam1_visit1.yaml").write_text("")
    _refused(capsys, ["check", str(SMOKE), "--cameras", str(empty), "--out", str(out)],
             f"--cameras {empty}: holds no camera file")  # fmt: skip
    assert not out.exists()


def test_a_camera_the_scenario_lacks_is_refused(cameras, tmp_path, capsys):
    folder = tmp_path / "cams"
    folder.mkdir()
    shutil.copy(cameras / "cam1_visit1.json", folder / "cam7_visit1.json")
    out = tmp_path / "check"
    _refused(capsys, ["check", str(SMOKE), "--cameras", str(folder), "--out", str(out)],
             str(folder / "cam7_visit1.json"), "camera 'cam7' is not in scenario 'smoke'",
             "its cameras: cam1")  # fmt: skip
    (folder / "cam7_visit1.json").rename(folder / "notes.json")
    _refused(capsys, ["check", str(SMOKE), "--cameras", str(folder), "--out", str(out)],
             str(folder / "notes.json"), "expected NAME_visitK.json")  # fmt: skip
    assert not out.exists()


GOOD = {**camera_identity(load_scenario(SMOKE)), **camera_to_dict(SMOKE_CAMERA)}
"""A camera file of the smoke room, as a run writes it."""


@pytest.mark.parametrize(
    ("data", "expected"),
    [
        ([GOOD], "expected a JSON object (a camera), got [{"),
        ({**GOOD, "f_px": "400"}, 'f_px: expected a positive finite number, got "400"'),
        ({**GOOD, "f_px": None}, "f_px: expected a positive finite number, got null"),
        ({**GOOD, "f_px": 0.0}, "f_px: expected a positive finite number, got 0.0"),
        ({**GOOD, "world2cam_t": [math.nan, 0.0, 0.0]}, "world2cam_t: holds NaN or infinity"),
        ({**GOOD, "position_m": [math.inf, 0.0, 0.0]}, "position_m: holds NaN or infinity"),
        ({**GOOD, "world2cam_r": [[1, 0, 0], [0, 1, 0], [0, 0, 2]]}, "world2cam_r: not a rotation"),
        ({**GOOD, "image_size": [640, 480]}, "image_size 640 x 480, but camera 'cam1'"),
        ({**GOOD, "scenario": "paper_hall"}, "calibrated in scenario 'paper_hall', not in"),
        ({**GOOD, "scenario_digest": "0" * 16, "site_digest": "1" * 16}, "its site changed"),
    ],
)
def test_a_bad_camera_file_is_refused_before_anything_moves(tmp_path, capsys, data, expected):
    folder = tmp_path / "cams"
    folder.mkdir()
    path = folder / "cam1_visit1.json"
    path.write_text(json.dumps(data))
    out = tmp_path / "check"
    args = ["check", str(SMOKE), "--cameras", str(folder), "--fidelity", "geometric"]
    _refused(capsys, [*args, "--out", str(out)], f"{path}: ", expected)
    assert not out.exists()


def test_an_unknown_camera_in_the_faults_is_refused(cameras, tmp_path, capsys):
    scenario = _variant(
        tmp_path, "bad", '[[faults.moved_cameras]]\ncamera = "cam9"\nshift = [0.02, 0.0, 0.0]\n'
    )
    out = tmp_path / "check"
    args = ["check", str(scenario), "--cameras", str(cameras), "--out", str(out)]
    issue = "faults.moved_cameras[0].camera: unknown camera (got 'cam9')"
    _refused(capsys, args, str(scenario), issue)
    assert not out.exists()


@pytest.mark.parametrize(
    ("extra", "expected"),
    [
        (["--stops", "1"], "expected 2 to 50"),
        (["--false-alarm-rate", "0"], "expected a number between 0 and 1"),
        (["--false-alarm-rate", "1.5"], "expected a number between 0 and 1"),
        (["--min-pixel-sigma", "-1"], "expected a finite number above 0"),
    ],
)
def test_bad_options_are_refused(tmp_path, capsys, extra, expected):
    args = ["check", str(SMOKE), "--cameras", str(tmp_path), "--out", str(tmp_path / "o")]
    with pytest.raises(SystemExit) as exit_:
        main([*args, *extra])
    assert exit_.value.code == 2
    assert expected in _said(capsys)


def test_twin_only_options_are_refused_with_a_rig(cameras, tmp_path, capsys):
    args = ["check", str(SMOKE), "--cameras", str(cameras), "--rig", str(tmp_path / "r.toml")]
    _refused(capsys, [*args, "--seed", "0"], "--seed apply to the twin, not to --rig")


def test_bad_input_is_refused_without_loading_the_twin(tmp_path):
    code = (
        "import sys; from twin.cli import main; rc = main(sys.argv[1:]); "
        "assert 'mujoco' not in sys.modules, 'mujoco was imported'; sys.exit(rc)"
    )
    run = subprocess.run(
        [sys.executable, "-c", code, "check", str(SMOKE), "--cameras", str(tmp_path / "none")],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 2, run.stderr
    assert "no such folder" in run.stdout
