"""Every conversion round-trips; the OpenCV export agrees with our projection."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from calib import OpenCVCamera, TsaiCamera, from_paper_units, to_paper_units, tsai2opencv
from calib.io import load_camera, save_camera
from calib.opencv_camera import image_grid
from calib.paper_units import PaperParameters, kappa1_mm2px, kappa1_px2mm
from calib.synthetic import paper_camera

angles = st.tuples(st.floats(-179.0, 179.0), st.floats(-85.0, 85.0), st.floats(-179.0, 179.0))
positions = st.tuples(*[st.floats(-5e4, 5e4, allow_nan=False)] * 3)


@given(
    f=st.floats(100.0, 3000.0),
    cx=st.floats(0.0, 320.0),
    cy=st.floats(0.0, 240.0),
    kappa_mm=st.floats(-1e-2, 1e-2),
    pos=positions,
    rot=angles,
    sx=st.floats(0.9, 1.1),
    pitch=st.floats(0.002, 0.02),
)
def test_paper_units_round_trip(f, cx, cy, kappa_mm, pos, rot, sx, pitch) -> None:
    p = PaperParameters(f, cx, cy, kappa_mm, pos, rot, sx, pitch)
    back = to_paper_units(from_paper_units(p), pitch)
    assert_allclose(back.f_px, f)
    assert_allclose([back.cx, back.cy, back.sx], [cx, cy, sx])
    assert_allclose(back.kappa1_per_mm2, kappa_mm, rtol=1e-12, atol=1e-300)
    assert_allclose(back.position_mm, pos, rtol=1e-9, atol=1e-6)
    assert_allclose(back.rotation_deg, rot, atol=1e-9)


@given(k=st.floats(-1e-5, 1e-5), pitch=st.floats(1e-4, 0.1))
def test_kappa_unit_conversion_round_trip(k: float, pitch: float) -> None:
    assert kappa1_mm2px(kappa1_px2mm(k, pitch), pitch) == pytest.approx(k, rel=1e-12)


def test_kappa_conversion_rejects_bad_pitch() -> None:
    with pytest.raises(ValueError, match="pixel_size_mm must be a positive number, got 0"):
        kappa1_px2mm(1e-7, 0)


def test_table_ii_camera_1_in_paper_units() -> None:
    p = to_paper_units(paper_camera(1), pixel_size_mm=0.015)
    assert_allclose(p.position_mm, [-3355.1, 10625.5, 2117.4])
    assert_allclose(p.rotation_deg, [115.5, -2.9, 178.2])
    assert p.kappa1_per_mm2 == pytest.approx(4.33e-7 / 0.015**2)


# Table II kappa1 magnitudes, read in 1/px^2 (the larger reading), of both signs, and a
# lens three times stronger than the strongest of them.
KAPPAS = [8.08e-8, 4.33e-7, 7.02e-7, -4.33e-7, -7.02e-7, 2.1e-6, -2.1e-6, 0.0]


@pytest.mark.parametrize("kappa1", KAPPAS)
def test_opencv_export_agrees_within_005_px(kappa1: float) -> None:
    cam = paper_camera(1, kappa1=kappa1, sx=1.01)
    conv = tsai2opencv(cam)
    grid = image_grid(cam.image_size, step=2.0)  # a denser grid than the fit used
    origins, dirs = cam.unproject(grid)
    pts = origins + 9.0 * dirs
    err = np.linalg.norm(conv.camera.project(pts) - cam.project(pts), axis=1)
    assert err.max() < 0.05
    assert conv.max_error_px < 0.05


@pytest.fixture
def cameras() -> list:
    tsai = paper_camera(3, sx=1.004)
    return [tsai, tsai2opencv(paper_camera(2)).camera]


def test_json_round_trip_is_exact(tmp_path, cameras) -> None:
    for i, cam in enumerate(cameras):
        path = tmp_path / f"cam{i}.json"
        save_camera(cam, path)
        back = load_camera(path)
        assert type(back) is type(cam)
        assert_allclose(back.world2cam_r, cam.world2cam_r, rtol=0, atol=0)
        assert_allclose(back.world2cam_t, cam.world2cam_t, rtol=0, atol=0)
        if isinstance(cam, TsaiCamera):
            assert back == cam
        else:
            assert_allclose(back.camera_matrix, cam.camera_matrix, rtol=0, atol=0)
            assert_allclose(back.dist_coeffs, cam.dist_coeffs, rtol=0, atol=0)


def test_opencv_yaml_round_trip(tmp_path, cameras) -> None:
    opencv_cam = cameras[1]
    path = tmp_path / "cam.yaml"
    save_camera(opencv_cam, path)
    back = load_camera(path)
    assert isinstance(back, OpenCVCamera)
    assert_allclose(back.camera_matrix, opencv_cam.camera_matrix, rtol=1e-15)
    assert_allclose(back.dist_coeffs, opencv_cam.dist_coeffs, rtol=1e-15)
    assert_allclose(back.world2cam_r, opencv_cam.world2cam_r, rtol=1e-15, atol=1e-16)
    assert_allclose(back.world2cam_t, opencv_cam.world2cam_t, rtol=1e-15)
    assert back.image_size == opencv_cam.image_size


def test_tsai_camera_through_opencv_yaml_projects_the_same(tmp_path, cameras) -> None:
    tsai = cameras[0]
    path = tmp_path / "cam.yml"
    save_camera(tsai, path)
    back = load_camera(path)
    grid = image_grid(tsai.image_size, step=8.0)
    origins, dirs = tsai.unproject(grid)
    pts = origins + 6.0 * dirs
    assert np.abs(back.project(pts) - grid).max() < 0.05


def test_ros_camera_info_round_trip(tmp_path, cameras) -> None:
    opencv_cam = cameras[1]
    path = tmp_path / "cam.camera_info.yaml"
    save_camera(opencv_cam, path, name="cam2")
    text = path.read_text()
    assert "camera_name: cam2" in text
    assert "distortion_model: plumb_bob" in text
    back = load_camera(path)
    assert_allclose(back.camera_matrix, opencv_cam.camera_matrix, rtol=0, atol=0)
    assert_allclose(back.dist_coeffs, opencv_cam.dist_coeffs, rtol=0, atol=0)
    # camera_info carries no pose: the identity is returned.
    assert_allclose(back.world2cam_r, np.eye(3))


@settings(max_examples=25, deadline=None)
@given(
    fx=st.floats(200, 2000), fy=st.floats(200, 2000), cx=st.floats(0, 640), cy=st.floats(0, 480),
    d=st.lists(st.floats(-1, 1), min_size=5, max_size=5),
)  # fmt: skip
def test_file_round_trips_for_any_opencv_camera(tmp_path_factory, fx, fy, cx, cy, d) -> None:
    cam = OpenCVCamera(np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1]]), d, image_size=(640, 480))
    folder = tmp_path_factory.mktemp("rt")
    for name in ("c.json", "c.yaml", "c.camera_info.yaml"):
        save_camera(cam, folder / name)
        back = load_camera(folder / name)
        assert_allclose(back.camera_matrix, cam.camera_matrix, rtol=1e-15)
        assert_allclose(back.dist_coeffs, cam.dist_coeffs, rtol=1e-15)


def test_unknown_camera_file_type(tmp_path, cameras) -> None:
    with pytest.raises(ValueError, match=r"unknown camera file type; use \.json"):
        save_camera(cameras[0], tmp_path / "cam.txt")


def test_camera_json_with_missing_key(tmp_path) -> None:
    path = tmp_path / "bad.json"
    path.write_text('{"model": "tsai", "image_size": [320, 240]}')
    with pytest.raises(ValueError, match=r"bad\.json: missing key 'world2cam_r'"):
        load_camera(path)
