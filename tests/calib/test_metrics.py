"""Table III metrics of T cameras equal calib.metrics.evaluate trial by trial, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calib.camera import TsaiCameras
from calib.metrics import evaluate, evaluate_batch, pose_errors
from calib.rotation import euler2matrix, rotation_angle_between
from calib.synthetic import led_points, paper_camera

TRIALS = 12


def perturbed_cameras(cam, rng: np.random.Generator) -> list:
    """TRIALS cameras around ``cam``: a few mm, mrad and px away."""
    out = []
    for _ in range(TRIALS):
        tilt = euler2matrix(rng.normal(0.0, 2e-3, 3))
        c = rng.normal(0.0, 5e-3, 3) + cam.position
        r = tilt @ cam.world2cam_r
        out.append(
            cam.with_(
                f=cam.f + rng.normal(0.0, 2.0),
                cx=cam.cx + rng.normal(0.0, 2.0),
                kappa1=cam.kappa1 * rng.uniform(0.8, 1.2),
                sx=1.0 + rng.normal(0.0, 1e-3),
                world2cam_r=r,
                world2cam_t=-r @ c,
            )
        )
    return out


def test_metrics_equal_evaluate_per_trial() -> None:
    cam = paper_camera(3)
    rng = np.random.default_rng(9)
    cams = perturbed_cameras(cam, rng)
    pts = led_points(cam, 60, rng)
    points = pts + rng.normal(0.0, 1.5e-3, (TRIALS, *pts.shape))
    pixels = cam.project(pts) + rng.normal(0.0, 0.3, (TRIALS, len(pts), 2))
    m = evaluate_batch(TsaiCameras.from_cameras(cams), points, pixels)
    assert m.n_points == len(pts)
    for k, c in enumerate(cams):
        ref = evaluate(c, points[k], pixels[k])
        for name in ("mean", "rms", "std", "max"):
            assert getattr(m.pixel, name)[k] == getattr(ref.pixel, name)
            assert getattr(m.error_3d, name)[k] == getattr(ref.error_3d, name)
            assert isinstance(getattr(ref.pixel, name), float)


def test_pose_errors_against_the_truth() -> None:
    cam = paper_camera(1)
    cams = perturbed_cameras(cam, np.random.default_rng(10))
    err = pose_errors(TsaiCameras.from_cameras(cams), cam)
    for k, c in enumerate(cams):
        assert_allclose(err.position_m[k], np.linalg.norm(c.position - cam.position), rtol=1e-9)
        angle = rotation_angle_between(c.world2cam_r, cam.world2cam_r)
        assert_allclose(err.rotation_rad[k], angle, rtol=1e-9)
    per_trial = pose_errors(TsaiCameras.from_cameras(cams), TsaiCameras.from_cameras(cams))
    assert np.abs(per_trial.position_m).max() == 0.0
    assert per_trial.rotation_rad.max() < 1e-12


def test_a_point_behind_its_camera_gives_nan_for_its_trial_only() -> None:
    cam = paper_camera(1)
    pts = led_points(cam, 20, np.random.default_rng(11))
    points = np.stack([pts, pts])
    points[1, 3] = 2 * cam.position - pts[3]
    pixels = np.stack([cam.project(pts)] * 2)
    m = evaluate_batch(TsaiCameras.from_cameras([cam, cam]), points, pixels)
    assert m.pixel.mean[0] < 1e-9
    assert np.isnan(m.pixel.mean[1])
    with pytest.raises(ValueError, match="behind the camera, first in row 3"):
        evaluate(cam, points[1], pixels[1])
