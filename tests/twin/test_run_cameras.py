"""The cameras a run wrote, read back for ``twin check``: the latest calibration of each,
and every problem named with its folder or file."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from calib.io.camera_files import camera_to_dict, save_camera
from calib.opencv_camera import tsai2opencv
from twin.run.run_cameras import CamerasFolderError, camera_identity, latest_cameras
from twin.scenario import Scenario, load_scenario
from twin.scenario.schema import Faults, MovedCamera

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


# -- the scenario a camera file belongs to -------------------------------------------------
HALL = load_scenario(ROOT / "scenarios" / "paper_hall.toml")


def _with(scenario: Scenario, **changes) -> Scenario:
    return scenario.model_copy(update=changes)


def test_a_file_of_another_scenario_is_refused_by_name(tmp_path):
    save_camera(CAMERA, tmp_path / "cam1_visit1.json", identity=camera_identity(HALL))
    with pytest.raises(CamerasFolderError) as err:
        latest_cameras(tmp_path, SMOKE)
    message = str(err.value)
    assert message.startswith(str(tmp_path / "cam1_visit1.json"))
    assert "calibrated in scenario 'paper_hall', not in scenario 'smoke'" in message


def test_a_file_of_the_same_name_and_another_site_is_refused_with_both_digests(tmp_path):
    space = SMOKE.space.model_copy(update={"size": (12.0, 6.0, 3.0)})
    then = camera_identity(_with(SMOKE, space=space))
    save_camera(CAMERA, tmp_path / "cam1_visit1.json", identity=then)
    now = camera_identity(SMOKE)
    with pytest.raises(CamerasFolderError, match="its site changed") as err:
        latest_cameras(tmp_path, SMOKE)
    message = str(err.value)
    assert f"digest {then['scenario_digest']}, site {then['site_digest']}" in message
    assert f"digest {now['scenario_digest']}, site {now['site_digest']}" in message


def test_the_twins_own_settings_and_the_procedure_leave_the_site_as_it_was(tmp_path):
    moved = Faults(moved_cameras=(MovedCamera(camera="cam1", shift=(0.02, 0.0, 0.0)),))
    campaign = SMOKE.campaign.model_copy(update={"reference_cameras": ()})
    for other in (
        _with(SMOKE, seed=9),
        SMOKE.without_noise(),
        _with(SMOKE, faults=moved),
        _with(SMOKE, campaign=campaign),
    ):
        identity = camera_identity(other)
        assert identity["scenario_digest"] != camera_identity(SMOKE)["scenario_digest"]
        assert identity["site_digest"] == camera_identity(SMOKE)["site_digest"]
        save_camera(CAMERA, tmp_path / "cam1_visit1.json", identity=identity)
        assert latest_cameras(tmp_path, SMOKE)["cam1"].camera.f == CAMERA.f
    camera = SMOKE.cameras[0].model_copy(update={"position": (6.0, 0.1, 1.6)})
    parent = SMOKE.robots.parent.model_copy(update={"start_xy": (0.0, 0.1)})
    for other in (
        _with(SMOKE, cameras=(camera,)),
        _with(SMOKE, robots=SMOKE.robots.model_copy(update={"parent": parent})),
    ):
        assert camera_identity(other)["site_digest"] != camera_identity(SMOKE)["site_digest"]


@pytest.mark.parametrize(
    ("camera", "expected"),
    [
        (CAMERA.with_(image_size=(640, 480)), ["image_size 640 x 480, but camera 'cam1' of "
         "scenario 'smoke'", "takes 320 x 240 images (the file records no scenario)"]),
        (SMOKE.camera("cam1").tsai().with_(world2cam_t=HALL.camera("cam1").tsai().world2cam_t),
         ["the camera lies at (10.84, 2.75, 1.88) m (the file records no scenario), outside the "
          "space of scenario 'smoke'", ": x -2 to 8, y -3 to 3, z -0.4 to 2.6 m, and 0.5 m "
          "more"]),
    ],
)  # fmt: skip
def test_an_older_file_of_another_site_is_refused(tmp_path, camera, expected):
    save_camera(camera, tmp_path / "cam1_visit1.json")  # no scenario recorded
    with pytest.raises(CamerasFolderError) as err:
        latest_cameras(tmp_path, SMOKE)
    message = str(err.value)
    assert message.startswith(str(tmp_path / "cam1_visit1.json"))
    for text in expected:
        assert text in message, message


def test_an_older_file_of_this_site_is_read(tmp_path):
    # Half a metre outside the walls is a calibration's error, not another site.
    inside = CAMERA.with_(world2cam_t=-CAMERA.world2cam_r @ np.array([8.4, 0.0, 1.6]))
    save_camera(inside, tmp_path / "cam1_visit1.json")
    assert latest_cameras(tmp_path, SMOKE)["cam1"].camera.position[0] == pytest.approx(8.4)
