"""The cameras a run wrote, read back for ``twin check``: the latest calibration of each,
and every problem named with its folder or file."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from calib.io.camera_files import camera_to_dict, save_camera
from calib.opencv_camera import tsai2opencv
from twin.run_cameras import CamerasFolderError, latest_cameras
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
SMOKE = load_scenario(ROOT / "scenarios" / "smoke.toml")
CAMERA = SMOKE.camera("cam1").tsai()


def _write(folder: Path, name: str, f: float = 400.0, covariance=None) -> None:
    save_camera(CAMERA.with_(f=f), folder / name, covariance=covariance)


def test_the_latest_calibration_of_each_camera_is_read(tmp_path):
    _write(tmp_path, "cam1_visit1.json", 401.0)
    _write(tmp_path, "cam1_visit2.json", 402.0, covariance=np.eye(11))
    _write(tmp_path, "cam1_visit2.yaml")  # the other formats are not read
    got = latest_cameras(tmp_path, SMOKE)["cam1"]
    assert got.visit == 2
    assert got.camera.f == 402.0
    assert got.covariance is not None
    _write(tmp_path, "cam1_check.json", 403.0)  # a check's re-posed camera comes last
    got = latest_cameras(tmp_path, SMOKE)["cam1"]
    assert got.visit is None
    assert got.camera.f == 403.0
    assert got.covariance is None


@pytest.mark.parametrize(
    ("setup", "expected"),
    [
        (lambda d: None, "holds no camera file"),
        (lambda d: (d / "cam1_visit1.yaml").write_text(""), "holds no camera file"),
        (lambda d: _write(d, "cam2_visit1.json"), "camera 'cam2' is not in scenario 'smoke'"),
        (lambda d: _write(d, "calibration.json"), "not a camera file of a run"),
        (lambda d: (d / "cam1_visit1.json").write_text("{"), "invalid JSON"),
    ],
)
def test_a_folder_that_cannot_be_checked_is_named(tmp_path, setup, expected):
    setup(tmp_path)
    with pytest.raises(CamerasFolderError, match=expected) as err:
        latest_cameras(tmp_path, SMOKE)
    assert str(tmp_path) in str(err.value)


def test_a_missing_folder_and_an_opencv_camera_are_refused(tmp_path):
    with pytest.raises(CamerasFolderError, match="no such folder"):
        latest_cameras(tmp_path / "nowhere", SMOKE)
    path = tmp_path / "cam1_visit1.json"
    path.write_text(json.dumps(camera_to_dict(tsai2opencv(CAMERA).camera)))
    with pytest.raises(CamerasFolderError, match="an OpenCV camera") as err:
        latest_cameras(tmp_path, SMOKE)
    assert str(path) in str(err.value)
