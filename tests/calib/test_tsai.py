"""Tsai calibration: simulate with a known camera, start from nothing, recover it."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.stats import f as f_law

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


# One calibration's errors against its reported covariance, over many data sets. For a
# least-squares estimate linear in the noise, with the covariance scaled by the residual
# variance, NEES / P = e^T C^-1 e / P follows Fisher's F(P, dof) law exactly; its
# cumulative probability u is uniform on (0, 1), whatever a single value's tail. The mean
# of n values of u is 1/2 within sqrt(1 / (12 n)); the band is 4 of those standard errors
# (two-sided: a false alarm once in 16 000 runs). Both sides count: a covariance too small
# (errors beyond it) pushes u up, one too large pulls it down. Each camera gives 4 point
# sets with 20 draws of pixel noise each: n = 240, band +-0.075.
PIT_K = 4.0
POINT_SETS, NOISE_DRAWS = 4, 20


def pit_mean_band(n: int) -> float:
    return PIT_K * np.sqrt(1.0 / (12.0 * n))


def nees_probability(res, truth: np.ndarray) -> float:
    """Cumulative probability of a calibration's NEES under its F law."""
    e = res.values - truth
    angles = np.isin(res.parameter_names, ("rx", "ry", "rz"))
    e[angles] = (e[angles] + np.pi) % (2 * np.pi) - np.pi
    p = len(e)
    return float(f_law.cdf(e @ np.linalg.solve(res.covariance, e) / p, p, res.dof))


LINEAR_PX = 0.05


def data_sets(index: int, sigma: float, seed: int):
    """(camera, points, noisy pixels) of camera ``index``: POINT_SETS point sets, each
    with NOISE_DRAWS draws of pixel noise ``sigma``."""
    cam = paper_camera(index)
    rng = np.random.default_rng(seed + index)
    for _ in range(POINT_SETS):
        pts = led_points(cam, 70, rng)
        uv = cam.project(pts)
        for _ in range(NOISE_DRAWS):
            yield cam, pts, uv + rng.normal(0.0, sigma, uv.shape)


def test_noisy_parameters_follow_their_reported_covariance() -> None:
    # At 0.05 px, where the estimator is linear in the noise. A reported standard
    # deviation 10 % too large moves the mean to 0.38, 10 % too small to 0.63. At the
    # paper's 0.3 px cx and ry are not linear in the noise (see test_statistics.py): the
    # mean is 0.58 and the NEES passes its 99 % quantile in 7 % of the data sets (450
    # measured), the reason a 3-sigma test of all eleven parameters on one data set failed
    # for about one seed in ten.
    u, sigma2 = [], []
    for index in (1, 2, 3):
        for cam, pts, uv in data_sets(index, LINEAR_PX, 900):
            res = calibrate_tsai(pts, uv, cam.image_size)
            assert res.dof == 2 * 70 - 11
            u.append(nees_probability(res, true_values(cam)))
            sigma2.append((res.sigma_px / LINEAR_PX) ** 2)
    assert abs(np.mean(u) - 0.5) < pit_mean_band(len(u)), np.mean(u)
    # The residual variance: chi-square over dof, mean 1 within sqrt(2 / (dof n)).
    assert abs(np.mean(sigma2) - 1.0) < PIT_K * np.sqrt(2.0 / (129 * len(sigma2)))


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
    # With noise: far tighter than a full calibration.
    noisy = uv + rng.normal(0, 0.3, uv.shape)
    res = calibrate_exterior(cam1_points, noisy, cam1)
    full = calibrate_tsai(cam1_points, noisy, cam1.image_size)
    assert np.all(res.std[3:] < full.std[8:])


def test_exterior_parameters_follow_their_reported_covariance() -> None:
    # The pose alone is linear enough at the paper's 0.3 px (measured over 600 data sets:
    # mean u 0.490, NEES beyond its 99 % quantile in 1.0 %). A reported standard deviation
    # 20 % too large moves the mean to 0.34, 10 % to 0.41 (caught three times in four).
    u = []
    for index in (1, 2, 3):
        for cam, pts, uv in data_sets(index, 0.3, 950):
            truth = np.concatenate([cam.rotation_rad, cam.position])
            u.append(nees_probability(calibrate_exterior(pts, uv, cam), truth))
    assert abs(np.mean(u) - 0.5) < pit_mean_band(len(u)), np.mean(u)


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
