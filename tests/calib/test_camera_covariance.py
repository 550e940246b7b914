"""A camera's covariance in frame-free terms: the pixels' derivatives, and the camera files
that carry it."""

from __future__ import annotations

import json

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calib.camera_covariance import CAMERA_PARAMETERS, camera_jacobian, perturbed_camera
from calib.io.camera_files import load_camera, load_camera_covariance, save_camera
from calib.synthetic import led_points, paper_camera
from calib.tsai import pixel_jacobian


def test_no_change_is_the_same_camera():
    camera = paper_camera(1)
    same = perturbed_camera(camera, np.zeros(11))
    assert_allclose(same.world2cam_r, camera.world2cam_r, atol=1e-15)
    assert_allclose(same.world2cam_t, camera.world2cam_t, atol=1e-15)


def test_the_jacobian_agrees_with_the_analytic_one():
    camera = paper_camera(1)
    points = led_points(camera, 12, np.random.default_rng(1))
    numeric = camera_jacobian(camera, points)
    analytic = pixel_jacobian(camera, points).reshape(-1, 11)
    # f, cx, cy, sx and the optical centre are the same parameters in both.
    for ours, theirs in ((0, 0), (1, 1), (2, 2), (3, 3), (8, 8), (9, 9), (10, 10)):
        assert_allclose(numeric[:, ours], analytic[:, theirs], rtol=1e-5, atol=1e-6)


def test_a_json_camera_file_carries_its_covariance(tmp_path):
    camera = paper_camera(1)
    rng = np.random.default_rng(2)
    a = rng.normal(size=(11, 11))
    cov = a @ a.T
    save_camera(camera, tmp_path / "c.json", covariance=cov)
    save_camera(camera, tmp_path / "c.yaml", covariance=cov)  # no place for it: left out
    assert_allclose(load_camera_covariance(tmp_path / "c.json"), cov, rtol=1e-15)
    assert load_camera_covariance(tmp_path / "c.yaml") is None
    assert load_camera(tmp_path / "c.json").f == camera.f
    data = json.loads((tmp_path / "c.json").read_text())
    assert data["covariance"]["parameters"] == list(CAMERA_PARAMETERS)
    save_camera(camera, tmp_path / "none.json")
    assert load_camera_covariance(tmp_path / "none.json") is None


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda c: c.update(parameters=["f"]), "covariance.parameters must be"),
        (lambda c: c["matrix"][0].__setitem__(1, 5.0), "symmetric"),
        (lambda c: c.update(matrix=[[1.0]]), "11 x 11"),
        (lambda c: c["matrix"][3].__setitem__(3, -1.0), "negative"),
    ],
)
def test_a_bad_covariance_is_refused_naming_the_file(tmp_path, change, message):
    path = tmp_path / "c.json"
    save_camera(paper_camera(1), path, covariance=np.eye(11))
    data = json.loads(path.read_text())
    change(data["covariance"])
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=message) as err:
        load_camera_covariance(path)
    assert str(path) in str(err.value)
