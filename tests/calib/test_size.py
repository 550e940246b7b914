"""Calibration memory grows linearly with the number of points.

A step whose memory grows with the square of the points (a full SVD of the (N, 8)
radial-alignment system builds an (N, N) matrix) passes every test on 70 points and takes
3.2 GB at 20,000. Linear growth, peak(N) = a + b N with a, b >= 0, bounds the peak at
10 N by ten times the peak at N; the bound carries a margin of 30% for the allocator's
bookkeeping. Both peaks are measured with tracemalloc in the same run, after a warm-up
calibration has done every import and cached whatever is cached.
"""

from __future__ import annotations

import tracemalloc
from collections.abc import Callable

import numpy as np
import pytest

from calib import CalibrationResult, calibrate_opencv, calibrate_tsai
from calib.synthetic import paper_camera, points_in_view

SMALL, LARGE = 2_000, 20_000
MARGIN = 1.3


def peak_bytes(calibrate: Callable[..., CalibrationResult], n_points: int) -> int:
    """Peak traced memory of one calibration on ``n_points`` noisy points, bytes."""
    cam = paper_camera(1)
    rng = np.random.default_rng(n_points)
    pts = points_in_view(cam, n_points, rng)
    uv = cam.project(pts) + rng.normal(0.0, 0.3, (n_points, 2))
    tracemalloc.start()
    try:
        res = calibrate(pts, uv, cam.image_size)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert res.n_points == n_points
    assert np.linalg.norm(res.camera.position - cam.position) < 5 * np.linalg.norm(res.std[-3:])
    return peak


@pytest.mark.parametrize("calibrate", [calibrate_tsai, calibrate_opencv], ids=["tsai", "opencv"])
def test_memory_grows_linearly_with_the_points(calibrate) -> None:
    peak_bytes(calibrate, 100)  # warm-up: imports and caches
    small = peak_bytes(calibrate, SMALL)
    large = peak_bytes(calibrate, LARGE)
    bound = MARGIN * (LARGE / SMALL) * small
    assert large < bound, (
        f"{LARGE} points took {large / 1e6:.1f} MB, {SMALL} took {small / 1e6:.1f} MB: "
        f"more than linear growth allows ({bound / 1e6:.1f} MB)"
    )
