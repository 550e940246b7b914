"""The check in the twin, against the truth (MuJoCo's sysid tests' style): a camera
calibrated by ``twin run`` on the smoke room is checked where the twin's world holds it:
unmoved, shifted 2 cm, turned 0.2 deg. The calibration and the checks use seed 3 (a
calibration of typical accuracy: ``benchmarks/bench_check.py`` measures 20 of them).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import chi2 as chi2_distribution

from calib.io.camera_files import camera_from_dict, load_camera_covariance
from calib.pose_change import moved_camera, pose_change
from twin.run.run_cameras import latest_cameras
from twin.run.runner import check_scenario, run_scenario
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[4]
SMOKE = ROOT / "scenarios" / "smoke.toml"
SEED = 3
CALIBRATION = 'visits = [{ camera = "cam1", station = [0.5, 0.0] }]'


def _variant(folder: Path, name: str, extra: str) -> Path:
    text = SMOKE.read_text(encoding="utf-8")
    assert CALIBRATION in text
    path = folder / f"{name}.toml"
    path.write_text(text.replace(CALIBRATION, CALIBRATION + "\n\n" + extra), encoding="utf-8")
    return path


def _moved(folder: Path, name: str, shift=(0.0, 0.0, 0.0), turn=(0.0, 0.0, 0.0)) -> Path:
    entry = (
        f'[[faults.moved_cameras]]\ncamera = "cam1"\nshift = {list(shift)}\n'
        f"turn_deg = {list(turn)}\n"
    )
    return _variant(folder, name, entry)


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory) -> Path:
    """The cameras/ folder of a geometric run of the smoke room."""
    out = tmp_path_factory.mktemp("run")
    # The paper's stops (4 LEDs each), which the counts below are of.
    run_scenario(
        SMOKE, out, fidelity="geometric", seed=SEED, report=False, overwrite=True, strategy="paper"
    )
    return out / "cameras"


def _check(scenario: Path, cameras: Path, out: Path, **kwargs) -> dict:
    kwargs.setdefault("strategy", "paper")
    results = check_scenario(scenario, cameras, out, fidelity="geometric", seed=SEED, **kwargs)
    assert json.loads((out / "check.json").read_text()) == results
    return results["cameras"]["cam1"]


def test_a_run_writes_each_cameras_covariance(calibrated):
    cov = load_camera_covariance(calibrated / "cam1_visit1.json")
    assert cov is not None
    position_std = np.sqrt(np.diag(cov)[8:])
    # The smoke room's camera, 70 points 2 to 6 m away: a few millimetres.
    assert np.all((position_std > 5e-4) & (position_std < 0.03))


def test_an_unmoved_camera_passes(calibrated, tmp_path):
    # At a false-alarm rate of 1e-6 an unmoved camera fails one check in a million; its
    # chi2 here (40 on 40 degrees of freedom) lies below half that threshold (97).
    c = _check(SMOKE, calibrated, tmp_path / "check", false_alarm_rate=1e-6)
    assert c["dof"] == 40
    assert c["threshold"] == pytest.approx(chi2_distribution.ppf(1 - 1e-6, 40))
    assert not c["moved"]
    assert c["chi2"] < 0.5 * c["threshold"]
    assert c["reposed"] is None
    assert c["files"] == []
    assert c["station"] == "first station"
    assert c["calibration"] == "cam1_visit1.json"
    assert c["calibration_covariance"] is True
    assert not (tmp_path / "check" / "cameras" / "cam1_check.json").exists()


@pytest.mark.parametrize(
    ("name", "shift", "turn"),
    [("shift", (0.02, 0.0, 0.0), (0.0, 0.0, 0.0)), ("turn", (0.0, 0.0, 0.0), (0.0, 0.2, 0.0))],
)
def test_a_2cm_shift_or_a_02deg_turn_is_found_and_reposed(calibrated, tmp_path, name, shift, turn):
    scenario = _moved(tmp_path, name, shift, turn)
    out = tmp_path / "check"
    c = _check(scenario, calibrated, out)
    assert c["moved"]
    assert c["chi2"] > 5 * c["threshold"]  # at the default false-alarm rate, 1e-3
    # The move found is the move made, within 4 of its predicted standard deviations.
    found = np.concatenate([c["turn_vector_deg"], c["shift_vector_mm"]])
    made = np.concatenate([turn, 1e3 * np.asarray(shift)])
    std = np.concatenate([c["turn_std_deg"], c["shift_std_mm"]])
    assert np.all(np.abs(found - made) < 4 * std), (found, made, std)
    assert c["shift_mm"] == pytest.approx(np.linalg.norm(c["shift_vector_mm"]))
    assert c["turn_deg"] == pytest.approx(np.linalg.norm(c["turn_vector_deg"]))
    # The re-posed camera is the truth, within its predicted covariance.
    reposed = camera_from_dict(c["reposed"])
    cov = load_camera_covariance(out / "cameras" / "cam1_check.json")
    assert cov is not None
    calibrated_camera = latest_cameras(calibrated, load_scenario(SMOKE))["cam1"].camera
    truth = moved_camera(
        calibrated_camera,
        1e-3 * np.asarray(c["truth"]["shift_vector_mm"]),
        np.radians(c["truth"]["turn_vector_deg"]),
    )
    shift_err, turn_err = pose_change(truth, reposed)
    error = np.concatenate([turn_err, shift_err])
    pose_cov = cov[5:, 5:]
    assert np.all(np.abs(error) < 4 * np.sqrt(np.diag(pose_cov)))
    assert error @ np.linalg.solve(pose_cov, error) < chi2_distribution.ppf(1 - 1e-4, 6)
    assert sorted(p.name for p in (out / "cameras").iterdir()) == [
        "cam1_check.camera_info.yaml",
        "cam1_check.json",
        "cam1_check.yaml",
    ]


def test_a_camera_the_first_station_does_not_see_is_checked_from_its_visit_station(
    calibrated, tmp_path
):
    # Naming no reference camera makes the first station see none: the group travels to
    # the camera's visit station by CPS, as the campaign does.
    scenario = _variant(tmp_path, "visit", "[campaign]\nreference_cameras = []\n")
    results = check_scenario(scenario, calibrated, tmp_path / "check", fidelity="geometric")
    c = results["cameras"]["cam1"]
    assert c["station"] == "visit station (0.5, 0)"
    assert results["distance_travelled_m"] == pytest.approx(0.5, abs=0.05)
    assert not c["moved"]
