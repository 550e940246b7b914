"""Tsai calibration: simulate with a known camera, start from nothing, recover it."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calib import DegenerateGeometryWarning, calibrate_exterior, calibrate_opencv, calibrate_tsai
from calib.synthetic import led_points, paper_camera
from calib.tsai import TSAI_PARAMETERS
from calib.tsai_linear import radial_alignment, tsai_initial_estimate


def true_values(cam) -> np.ndarray:
    return np.concatenate(
        [[cam.f, cam.cx, cam.cy, cam.sx, cam.kappa1], cam.rotation_rad, cam.position]
    )


def test_noise_free_recovers_every_parameter(paper_cam) -> None:
    cam = paper_cam.with_(sx=1.013)  # an sx that is not 1, so it must be found
    pts = led_points(cam, 70, np.random.default_rng(11))
    res = calibrate_tsai(pts, cam.project(pts), cam.image_size)
    assert res.parameter_names == TSAI_PARAMETERS
    assert_allclose(res.values, true_values(cam), rtol=1e-6)
    assert res.metrics.pixel.max < 1e-8
    assert res.metrics.error_3d.max < 1e-9


def test_noisy_parameters_within_three_sigma(paper_cam) -> None:
    rng = np.random.default_rng(12)
    pts = led_points(paper_cam, 70, rng)
    uv = paper_cam.project(pts) + rng.normal(0.0, 0.3, (70, 2))
    res = calibrate_tsai(pts, uv, paper_cam.image_size)
    z = (res.values - true_values(paper_cam)) / res.std
    assert np.all(np.abs(z) < 3.0), dict(zip(res.parameter_names, z.round(2), strict=True))
    assert res.sigma_px == pytest.approx(0.3, rel=0.2)
    assert res.dof == 2 * 70 - 11


def seven_points(cam) -> np.ndarray:
    """7 LED points from 7 different robot positions (4 heights, not coplanar)."""
    return led_points(cam, 70, np.random.default_rng(5))[::10]


def test_linear_stage_is_exact_from_seven_points(cam1) -> None:
    pts = seven_points(cam1)
    uv = cam1.project(pts)  # with distortion
    ra = radial_alignment(pts, cam1.with_(kappa1=0.0).project(pts), cam1.cx, cam1.cy)
    # Radial alignment is exact without distortion when the centre is right.
    assert_allclose(ra.world2cam_r, cam1.world2cam_r, atol=1e-9)
    assert_allclose([ra.tx, ra.ty], cam1.world2cam_t[:2], atol=1e-9)
    assert ra.sx == pytest.approx(cam1.sx, rel=1e-9)
    # ... and insensitive to radial distortion, which only moves points along their radius.
    ra_d = radial_alignment(pts, uv, cam1.cx, cam1.cy)
    assert_allclose(ra_d.world2cam_r, cam1.world2cam_r, atol=1e-9)


def test_full_calibration_from_seven_points_notes_the_few_dof(cam1) -> None:
    pts = seven_points(cam1)
    with pytest.warns(DegenerateGeometryWarning, match="only 3 degrees of freedom"):
        res = calibrate_tsai(pts, cam1.project(pts), cam1.image_size)
    assert res.dof == 3
    assert_allclose(res.camera.position, cam1.position, atol=1e-6)


def test_initial_estimate_is_close_with_the_wrong_centre() -> None:
    cam = paper_camera(2)  # its image centre is 10 px off the middle of the image
    pts = led_points(cam, 70, np.random.default_rng(2))
    init = tsai_initial_estimate(pts, cam.project(pts), cam.image_size)
    assert init.f == pytest.approx(cam.f, rel=0.01)
    assert np.linalg.norm(-init.world2cam_r.T @ init.world2cam_t - cam.position) < 0.1


def test_exterior_calibration_of_a_moved_camera(cam1, cam1_points) -> None:
    rng = np.random.default_rng(21)
    moved = cam1.with_(
        world2cam_r=cam1.world2cam_r, world2cam_t=cam1.world2cam_t + np.array([0.05, -0.02, 0.1])
    )
    uv = moved.project(cam1_points)
    res = calibrate_exterior(cam1_points, uv, cam1)
    assert_allclose(res.camera.position, moved.position, atol=1e-9)
    assert_allclose(res.camera.world2cam_r, moved.world2cam_r, atol=1e-10)
    # With noise: within 3 sigma, and far tighter than a full calibration.
    noisy = uv + rng.normal(0, 0.3, uv.shape)
    res = calibrate_exterior(cam1_points, noisy, cam1)
    z = (res.values[3:] - moved.position) / res.std[3:]
    assert np.all(np.abs(z) < 3.0)
    full = calibrate_tsai(cam1_points, noisy, cam1.image_size)
    assert np.all(res.std[3:] < full.std[8:])


def test_exterior_works_on_coplanar_points(cam1, cam1_points) -> None:
    floor = cam1_points.copy()
    floor[:, 2] = -0.383
    keep = cam1.in_image(cam1.project(floor))
    res = calibrate_exterior(floor[keep], cam1.project(floor[keep]), cam1)
    assert_allclose(res.camera.position, cam1.position, atol=1e-8)


def test_opencv_model_fits_a_tsai_lens(cam1, cam1_points) -> None:
    rng = np.random.default_rng(4)
    uv = cam1.project(cam1_points)
    res = calibrate_opencv(cam1_points, uv, cam1.image_size)
    assert res.model == "opencv"
    assert res.parameter_names[:6] == ("fx", "fy", "cx", "cy", "k1", "k2")
    # Two radial terms reproduce Tsai's one-term lens to well under the detection noise.
    assert res.metrics.pixel.max < 0.01
    assert_allclose(res.camera.position, cam1.position, atol=2e-3)
    noisy = calibrate_opencv(cam1_points, uv + rng.normal(0, 0.3, uv.shape), cam1.image_size)
    assert np.isfinite(noisy.std).all()
    assert np.linalg.norm(noisy.camera.position - cam1.position) < 5 * np.linalg.norm(
        noisy.std[-3:]
    )


def test_opencv_model_options_free_more_coefficients(cam1, cam1_points) -> None:
    uv = cam1.project(cam1_points)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DegenerateGeometryWarning)
        res = calibrate_opencv(cam1_points, uv, cam1.image_size, tangential=True, k3=True)
    assert res.parameter_names[4:9] == ("k1", "k2", "p1", "p2", "k3")
    assert res.metrics.pixel.max < 0.01


@pytest.mark.parametrize("index", [1, 2, 3])
def test_robust_over_many_noisy_data_sets(index: int) -> None:
    # 1 px noise (three times the paper's detection noise) on fresh point sets: the
    # closed-form start must lead the optimisation to the truth every time.
    cam = paper_camera(index)
    rng = np.random.default_rng(100 + index)
    for _ in range(6):
        pts = led_points(cam, 70, rng)
        uv_true = cam.project(pts)
        for _ in range(10):
            res = calibrate_tsai(pts, uv_true + rng.normal(0, 1.0, uv_true.shape), cam.image_size)
            assert np.linalg.norm(res.camera.position - cam.position) < 6 * np.linalg.norm(
                res.std[8:]
            )


def test_world_origin_far_away_or_in_the_cameras_y_plane() -> None:
    cam = paper_camera(1)
    pts = led_points(cam, 70, np.random.default_rng(8))
    # (a) the whole scene 5 km from the world origin;
    offset = np.array([5000.0, -3000.0, 20.0])
    far = cam.with_(world2cam_t=cam.world2cam_t - cam.world2cam_r @ offset)
    res = calibrate_tsai(pts + offset, far.project(pts + offset), far.image_size)
    assert_allclose(res.camera.position, far.position, rtol=1e-9)
    # (b) the world origin on the camera's y_c = 0 plane (Ty = 0), where Tsai's original
    # linear stage divides by zero.
    shift = cam.world2cam_r.T @ np.array([0.0, cam.world2cam_t[1], 0.0])
    flat = cam.with_(world2cam_t=cam.world2cam_t - cam.world2cam_r @ shift)
    assert abs(flat.world2cam_t[1]) < 1e-12
    res = calibrate_tsai(pts + shift, flat.project(pts + shift), flat.image_size)
    assert_allclose(res.camera.position, flat.position, atol=1e-9)
