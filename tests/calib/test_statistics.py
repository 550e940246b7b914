"""The reported uncertainty is right, and the estimator reaches the Cramer-Rao bound.

One Monte-Carlo of 400 calibrations of camera 1 (70 LED points, 0.3 px pixel noise) with a
fixed seed. The relative standard error of a standard deviation estimated from 400 samples
is 1/sqrt(2 * 400) = 3.5%, so the 25% and 10% tolerances are 7 and 3 standard errors wide.
"""

from __future__ import annotations

import numpy as np
import pytest

from calib import calibrate_tsai, predicted_covariance
from calib.synthetic import led_points, paper_camera
from calib.tsai import TSAI_PARAMETERS

SIGMA_PX = 0.3
TRIALS = 400


@pytest.fixture(scope="module")
def monte_carlo():
    cam = paper_camera(1)
    rng = np.random.default_rng(2024)
    pts = led_points(cam, 70, rng)
    uv = cam.project(pts)
    truth = np.concatenate(
        [[cam.f, cam.cx, cam.cy, cam.sx, cam.kappa1], cam.rotation_rad, cam.position]
    )
    estimates, reported_std = [], []
    for _ in range(TRIALS):
        res = calibrate_tsai(pts, uv + rng.normal(0.0, SIGMA_PX, uv.shape), cam.image_size)
        estimates.append(res.values)
        reported_std.append(res.std)
    return cam, pts, truth, np.array(estimates), np.array(reported_std)


@pytest.mark.slow
def test_reported_std_matches_monte_carlo_spread(monte_carlo) -> None:
    _, _, _, est, reported = monte_carlo
    spread = est.std(axis=0, ddof=1)
    ratio = reported.mean(axis=0) / spread
    bad = {n: round(r, 3) for n, r in zip(TSAI_PARAMETERS, ratio, strict=True) if abs(r - 1) > 0.25}
    assert not bad, f"reported std / Monte-Carlo std outside 1 +- 0.25: {bad}"


@pytest.mark.slow
def test_estimator_reaches_the_cramer_rao_bound(monte_carlo) -> None:
    cam, pts, truth, est, _ = monte_carlo
    crlb = np.sqrt(np.diag(predicted_covariance(cam, pts, SIGMA_PX)))
    rms = np.sqrt(np.mean((est - truth) ** 2, axis=0))
    checked = ["f_px", "cx", "cy", "x", "y", "z"]
    idx = [TSAI_PARAMETERS.index(n) for n in checked]
    ratio = rms[idx] / crlb[idx]
    bad = {n: round(r, 3) for n, r in zip(checked, ratio, strict=True) if abs(r - 1) > 0.10}
    assert not bad, f"Monte-Carlo RMS error / Cramer-Rao bound outside 1 +- 0.10: {bad}"
