"""Batched Tsai calibration: the per-trial scipy solution, exact recovery, no mixing."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from calib import calibrate_tsai
from calib.camera import TsaiCameras
from calib.point_errors import covariance_from_point_errors, position_covariance_from_blocks
from calib.rotation import euler2matrix
from calib.synthetic import led_points, paper_camera
from calib.tsai import TSAI_PARAMETERS, predicted_covariance
from calib.tsai_lm import TsaiBatchResult, calibrate_tsai_batch
from calib.tsai_parameters import INVALID_PX, pack

TRIALS = 50


def true_values(cam) -> np.ndarray:
    return np.concatenate(
        [[cam.f, cam.cx, cam.cy, cam.sx, cam.kappa1], cam.rotation_rad, cam.position]
    )


def off_start(cam):
    """A start some standard deviations away from the camera in every parameter."""
    tilt = euler2matrix([0.002, -0.001, 0.001])
    return cam.with_(
        f=cam.f + 2.0, cx=cam.cx - 3.0, kappa1=1.2 * cam.kappa1, world2cam_r=tilt @ cam.world2cam_r
    )


@pytest.fixture(scope="module")
def visit():
    """A Monte-Carlo visit of camera 1: the noise-free calibration on 70 LED points, and
    TRIALS trials with pixel noise of 0.05-0.3 px and 3D point noise of 1-2 mm."""
    cam = paper_camera(1)
    rng = np.random.default_rng(21)
    pts = led_points(cam, 70, rng)
    uv = cam.project(pts)
    start = calibrate_tsai(pts, uv, cam.image_size).camera
    sigma_px = rng.uniform(0.05, 0.3, TRIALS)[:, None, None]
    sigma_m = rng.uniform(1e-3, 2e-3, TRIALS)[:, None, None]
    points = pts + sigma_m * rng.normal(size=(TRIALS, *pts.shape))
    pixels = uv + sigma_px * rng.normal(size=(TRIALS, *uv.shape))
    return cam, start, points, pixels


@pytest.fixture(scope="module")
def batch(visit) -> TsaiBatchResult:
    cam, start, points, pixels = visit
    return calibrate_tsai_batch(points, pixels, cam.image_size, start)


def test_each_trial_agrees_with_calibrate_tsai(visit, batch) -> None:
    # Both minimise the same residual: the batch stops within 1e-6 of its own standard
    # deviations of the minimum, scipy's LM at its 1e-15 tolerances, so the two agree far
    # inside 1e-4 standard deviations, and covariances taken 1e-4 sigma apart within 1e-6.
    cam, _, points, pixels = visit
    refs = [calibrate_tsai(p, uv, cam.image_size) for p, uv in zip(points, pixels, strict=True)]
    values = np.array([r.values for r in refs])
    std = np.array([r.std for r in refs])
    diff = batch.values - values
    diff[:, 5:8] = np.angle(np.exp(1j * diff[:, 5:8]))
    assert batch.converged.all()
    assert batch.parameter_names == TSAI_PARAMETERS
    assert np.abs(diff / std).max() < 1e-4
    assert_allclose(batch.std, std, rtol=1e-6)
    position_std = np.sqrt(np.diagonal(batch.position_covariance, axis1=1, axis2=2))
    assert_allclose(position_std, std[:, 8:11], rtol=1e-6)
    scale = std[:, :, None] * std[:, None, :]  # covariances as correlations
    cov = np.array([r.covariance for r in refs])
    assert_allclose(batch.covariance / scale, cov / scale, rtol=0, atol=1e-6)
    assert_allclose(batch.sigma_px, [r.sigma_px for r in refs], rtol=1e-9)
    assert batch.dof == refs[0].dof


def test_trial_k_of_a_batch_is_a_batch_of_trial_k_bit_for_bit(visit, batch) -> None:
    cam, start, points, pixels = visit
    fields = ("q", "values", "covariance", "covariance_q", "sigma_px", "converged")
    for k in range(TRIALS):
        one = calibrate_tsai_batch(points[k : k + 1], pixels[k : k + 1], cam.image_size, start)
        for name in (*fields, "iterations", "world2cam_r"):
            assert_array_equal(getattr(batch, name)[k], getattr(one, name)[0], err_msg=name)
    backwards = calibrate_tsai_batch(points[::-1], pixels[::-1], cam.image_size, start)
    in_blocks = calibrate_tsai_batch(points, pixels, cam.image_size, start, block=7)
    for name in fields:
        assert_array_equal(getattr(backwards, name)[::-1], getattr(batch, name), err_msg=name)
        assert_array_equal(getattr(in_blocks, name), getattr(batch, name), err_msg=name)


def test_noise_free_data_recover_the_camera_exactly() -> None:
    cam = paper_camera(1).with_(sx=1.013)  # an sx that is not 1, so it must be found
    rng = np.random.default_rng(5)
    points = np.stack([led_points(cam, 70, rng) for _ in range(TRIALS)])
    pixels = np.stack([cam.project(p) for p in points])
    res = calibrate_tsai_batch(points, pixels, cam.image_size, off_start(cam))
    assert res.converged.all()
    assert (res.iterations > 0).all()
    assert np.abs(res.position - cam.position).max() < 1e-9
    assert_allclose(res.values, np.broadcast_to(true_values(cam), res.values.shape), rtol=1e-9)
    assert res.sigma_px.max() < 1e-9


def test_trial_k_as_a_camera(visit, batch) -> None:
    cam, _, points, _ = visit
    k = 7
    trial = batch.camera(k)
    assert trial.image_size == cam.image_size
    assert_array_equal(trial.world2cam_r, batch.world2cam_r[k])
    assert_allclose(trial.position, batch.position[k], rtol=0, atol=1e-12)
    assert_allclose(
        true_values(trial), batch.values[k], rtol=1e-12, atol=1e-15
    )  # the reported values describe this camera
    assert_allclose(trial.project(points[k]), batch.cameras.project_or_nan(points)[k], atol=1e-9)
    assert len(batch) == TRIALS


def test_start_from_parameters_and_shared_points(visit) -> None:
    cam, start, points, pixels = visit
    pts = points[0]
    a = calibrate_tsai_batch(pts, pixels[:3], cam.image_size, start)
    b = calibrate_tsai_batch(np.stack([pts] * 3), pixels[:3], cam.image_size, pack(start))
    assert_array_equal(a.q, b.q)


def test_too_few_iterations_are_reported_as_not_converged() -> None:
    cam = paper_camera(1)
    pts = led_points(cam, 70, np.random.default_rng(2))
    res = calibrate_tsai_batch(pts, cam.project(pts)[None], cam.image_size, off_start(cam),
                               max_iterations=1)  # fmt: skip
    assert not res.converged[0]
    assert res.iterations[0] == 1


def test_a_degenerate_trial_is_flagged_and_leaves_the_others_alone(visit, batch) -> None:
    # Trial 1 sees one point 70 times: its data determine 2 of the 11 parameters.
    cam, start, points, pixels = visit
    pts, uv = points[:3].copy(), pixels[:3].copy()
    pts[1], uv[1] = pts[1, 0], uv[1, 0]
    res = calibrate_tsai_batch(pts, uv, cam.image_size, start)
    assert_array_equal(res.converged, [True, False, True])
    assert np.isnan(res.covariance[1]).all()
    for k in (0, 2):
        assert_array_equal(res.q[k], batch.q[k])
        assert_array_equal(res.covariance[k], batch.covariance[k])


@pytest.mark.parametrize(
    ("points_shape", "pixels_shape", "match"),
    [
        ((4, 70, 3), (4, 70), "pixels"),
        ((4, 69, 3), (4, 70, 2), "points"),
        ((4, 5, 3), (4, 5, 2), "at least 6"),
    ],
)
def test_bad_shapes_are_refused(points_shape, pixels_shape, match) -> None:
    cam = paper_camera(1)
    with pytest.raises(ValueError, match=match):
        calibrate_tsai_batch(np.ones(points_shape), np.ones(pixels_shape), cam.image_size, cam)


def test_a_start_of_another_image_size_is_refused() -> None:
    cam = paper_camera(1)
    with pytest.raises(ValueError, match="image size"):
        calibrate_tsai_batch(np.ones((2, 8, 3)), np.ones((2, 8, 2)), (640, 480), cam)


def shared_stop_covariance(n: int, per_stop: int, sigma_m: float) -> np.ndarray:
    """(3n, 3n) covariance of points whose groups of ``per_stop`` share one offset."""
    stop = np.arange(n) // per_stop
    return np.kron((stop[:, None] == stop[None, :]).astype(float), np.eye(3)) * sigma_m**2


def test_point_error_covariance_is_the_first_order_map() -> None:
    # Points moved along one direction u by eps move the calibration by eps H u, so for
    # Sigma = eps^2 u u^T the covariance is the outer product of that move. At eps = 1e-7
    # (1.4 um per point) the second-order terms are ~1e-5 of it; the fit stops within
    # 1e-6 x 1e-4 px of its minimum (its xtol times its floor on sigma): ~1e-5 of the move,
    # but for parameters that hardly move (sx) that floor counts, as ``still`` below.
    cam = paper_camera(1)
    rng = np.random.default_rng(4)
    pts = led_points(cam, 70, rng)
    uv = cam.project(pts)
    eps = 1e-7
    u = rng.normal(size=(3, pts.size))
    res = calibrate_tsai_batch(pts + eps * u.reshape(3, *pts.shape), np.stack([uv] * 3),
                               cam.image_size, cam)  # fmt: skip
    moved = res.values - true_values(cam)
    still = 1e-9 * np.sqrt(np.diag(predicted_covariance(cam, pts, 1.0)))
    assert res.converged.all()
    for k in range(3):
        cov = covariance_from_point_errors(cam, pts, eps**2 * np.outer(u[k], u[k]))
        predicted = np.sqrt(np.diag(cov))
        assert (np.abs(predicted - np.abs(moved[k])) <= 1e-3 * predicted + still).all()
        position = moved[k, 8:11]
        assert_allclose(cov[8:11, 8:11], np.outer(position, position), rtol=2e-3)


def test_point_error_covariance_predicts_the_monte_carlo_scatter() -> None:
    # LEDs of one stop share a 2 mm offset. With 800 trials a standard deviation is
    # estimated within sqrt(1 / (2 * 800)) = 2.5 % (1 sigma): the band is 4 of those, plus
    # 1 % for the second-order terms of 2 mm errors.
    cam = paper_camera(1)
    rng = np.random.default_rng(6)
    pts = led_points(cam, 68, rng)
    n, trials = len(pts), 800
    cov_p = shared_stop_covariance(n, 4, 2e-3)
    offsets = rng.normal(0.0, 2e-3, (trials, n // 4, 3))
    points = pts + np.repeat(offsets, 4, axis=1)
    res = calibrate_tsai_batch(points, np.stack([cam.project(pts)] * trials), cam.image_size, cam)
    predicted = np.sqrt(np.diag(covariance_from_point_errors(cam, pts, cov_p))[8:11])
    assert res.converged.all()
    assert_allclose(res.position.std(axis=0), predicted, rtol=4 * np.sqrt(1 / (2 * trials)) + 0.01)


def test_point_error_covariance_adds_the_pixel_noise_bound() -> None:
    cam = paper_camera(2)
    pts = led_points(cam, 40, np.random.default_rng(8))
    cov_p = shared_stop_covariance(len(pts), 4, 1e-3)
    points_only = covariance_from_point_errors(cam, pts, cov_p)
    both = covariance_from_point_errors(
        TsaiCameras.from_cameras([cam, cam]), pts, cov_p, sigma_px=[0.0, 0.3]
    )
    assert_allclose(both[0], points_only, rtol=1e-12)
    pixel_part = both[1] - points_only
    assert_allclose(np.diag(pixel_part), np.diag(predicted_covariance(cam, pts, 0.3)), rtol=1e-6)


def test_block_covariance_is_the_joint_one_also_for_trials_that_lost_points() -> None:
    # Stops of four LEDs with full 12 x 12 blocks (correlated within a stop). Trial 0 keeps
    # all 40 points; trial 1 lost its third stop and keeps the other 36 in the same layout:
    # both equal the position block of the joint covariance of the points they kept.
    cam = paper_camera(2)
    rng = np.random.default_rng(9)
    pts = led_points(cam, 40, rng)
    factors = rng.normal(0.0, 1e-3, (10, 12, 6))
    blocks = factors @ np.swapaxes(factors, 1, 2)  # (10, 12, 12), rank 6 as a marker's
    joint = np.zeros((120, 120))
    for s in range(10):
        joint[12 * s : 12 * s + 12, 12 * s : 12 * s + 12] = blocks[s]
    kept = np.ones(40, dtype=bool)
    kept[8:12] = False
    cols = (3 * np.flatnonzero(kept)[:, None] + np.arange(3)).ravel()
    cams = TsaiCameras.from_cameras([cam])
    full = position_covariance_from_blocks(cams, pts[None], blocks[None])
    assert_allclose(full[0], covariance_from_point_errors(cam, pts, joint)[8:11, 8:11], rtol=1e-10)
    lost = position_covariance_from_blocks(cams, pts[kept][None], blocks[None], cols[None])
    expected = covariance_from_point_errors(cam, pts[kept], joint[np.ix_(cols, cols)])
    assert_allclose(lost[0], expected[8:11, 8:11], rtol=1e-10)
    with pytest.raises(ValueError, match="cannot hold 40 points"):
        position_covariance_from_blocks(cams, pts[None], blocks[None, :9])


def test_shared_errors_add_their_part_of_the_joint_covariance() -> None:
    # An error common to several stops (a marker's surveying error, the same at each stop
    # of a child): loadings S on a standard normal vector add S S^T to the joint covariance,
    # also for a trial that lost points.
    cam = paper_camera(2)
    rng = np.random.default_rng(10)
    pts = led_points(cam, 40, rng)
    factors = rng.normal(0.0, 1e-3, (10, 12, 6))
    blocks = factors @ np.swapaxes(factors, 1, 2)
    shared = rng.normal(0.0, 2e-3, (120, 24))
    joint = shared @ shared.T
    for s in range(10):
        joint[12 * s : 12 * s + 12, 12 * s : 12 * s + 12] += blocks[s]
    kept = np.ones(40, dtype=bool)
    kept[20:24] = False
    cols = (3 * np.flatnonzero(kept)[:, None] + np.arange(3)).ravel()
    cams = TsaiCameras.from_cameras([cam])
    full = position_covariance_from_blocks(cams, pts[None], blocks[None], shared=shared)
    assert_allclose(full[0], covariance_from_point_errors(cam, pts, joint)[8:11, 8:11], rtol=1e-10)
    lost = position_covariance_from_blocks(
        cams, pts[kept][None], blocks[None], cols[None], shared[None]
    )
    expected = covariance_from_point_errors(cam, pts[kept], joint[np.ix_(cols, cols)])
    assert_allclose(lost[0], expected[8:11, 8:11], rtol=1e-10)
    with pytest.raises(ValueError, match="shared must be"):
        position_covariance_from_blocks(cams, pts[None], blocks[None], shared=shared[:60])


def test_a_solution_with_points_behind_the_camera_is_not_converged() -> None:
    # A point behind the camera does not project: its residual is the pixel INVALID_PX
    # minus the observed one. Trial 1 observed it there (its residual 0) and the other 39
    # exactly: the fit is exact and the steps stop at once, yet a calibration with a point
    # behind the camera, even 1 cm behind, is no solution. Trial 2 has every point behind
    # (reflected through the optical centre). Trial 0 is the data as observed.
    cam = paper_camera(1)
    pts = led_points(cam, 40, np.random.default_rng(8))
    uv = cam.project(pts)
    one, uv_one = pts.copy(), uv.copy()
    axis = cam.world2cam_r[2]  # the optical axis in W
    one[7], uv_one[7] = cam.position - 0.01 * axis, INVALID_PX
    mirrored = 2.0 * cam.position - pts
    res = calibrate_tsai_batch(np.stack([pts, one, mirrored]), np.stack([uv, uv_one, uv]),
                               cam.image_size, cam)  # fmt: skip
    assert np.abs(res.position[:2] - cam.position).max() < 1e-9
    assert res.sigma_px[:2].max() < 1e-9
    assert res.iterations[1] == 0
    assert_array_equal(res.converged, [True, False, False])
