"""Every bad input gets a ValueError that names the problem and the number that was wrong."""

from __future__ import annotations

import numpy as np
import pytest

from calib import DegenerateGeometryWarning, calibrate_exterior, calibrate_opencv, calibrate_tsai
from calib.synthetic import led_points, paper_camera
from calib.tsai_linear import radial_alignment

SIZE = (320, 240)


@pytest.fixture
def data():
    cam = paper_camera(1)
    pts = led_points(cam, 70, np.random.default_rng(9))
    return cam, pts, cam.project(pts)


def test_too_few_points(data) -> None:
    cam, pts, uv = data
    with pytest.raises(ValueError, match=r"Tsai calibration .* needs at least 7 points, got 6"):
        calibrate_tsai(pts[:6], uv[:6], SIZE)
    with pytest.raises(
        ValueError, match=r"radial-alignment stage .* needs at least 7 points, got 5"
    ):
        radial_alignment(pts[:5], uv[:5], 160, 120)
    with pytest.raises(ValueError, match=r"exterior calibration .* needs at least 4 points, got 3"):
        calibrate_exterior(pts[:3], uv[:3], cam)
    with pytest.raises(
        ValueError, match=r"OpenCV-model calibration .* needs at least 7 points, got 6"
    ):
        calibrate_opencv(pts[:6], uv[:6], SIZE)


def test_coplanar_points(data) -> None:
    cam, pts, _ = data
    flat = pts.copy()
    flat[:, 2] = 0.1
    uv = cam.project(flat)
    keep = cam.in_image(uv)
    with pytest.raises(ValueError, match=r"the \d+ points are coplanar .* = \d\.\d\de-\d+"):
        calibrate_tsai(flat[keep], uv[keep], SIZE)
    with pytest.raises(ValueError, match="coplanar"):
        calibrate_opencv(flat[keep], uv[keep], SIZE)


def test_collinear_points(data) -> None:
    cam, pts, _ = data
    line = pts[0] + np.linspace(0, 1, 10)[:, None] * np.array([0.3, 0.5, 0.2])
    uv = cam.project(line)
    with pytest.raises(ValueError, match="the 10 points are collinear"):
        calibrate_tsai(line, uv, SIZE)
    with pytest.raises(ValueError, match="the 10 points are collinear"):
        calibrate_exterior(line, uv, cam)


def test_nearly_coplanar_points_warn_with_condition_number(data) -> None:
    cam, pts, _ = data
    flat = pts.copy()
    flat[:, 2] = -0.38 + 1e-5 * np.random.default_rng(0).standard_normal(len(pts))
    uv = cam.project(flat)
    keep = cam.in_image(uv)
    # 10 um of height spread over metres: warned with the condition number. Noise-free
    # data still determine the camera ...
    with pytest.warns(DegenerateGeometryWarning, match=r"nearly coplanar \(condition number"):
        res = calibrate_tsai(flat[keep], uv[keep], SIZE)
    np.testing.assert_allclose(res.camera.position, cam.position, atol=1e-9)
    # ... but with 0.3 px of noise they do not, and the error says why.
    noisy = uv[keep] + np.random.default_rng(1).normal(0, 0.3, (keep.sum(), 2))
    with (
        pytest.warns(DegenerateGeometryWarning),
        pytest.raises(ValueError, match=r"too close to coplanar .* condition number 1\.2e\+05"),
    ):
        calibrate_tsai(flat[keep], noisy, SIZE)


def test_thin_point_clouds_warn_and_report_their_uncertainty(data) -> None:
    # 1 cm of height spread over 5 m: calibrates, warns, and the standard deviation of f is
    # far larger than with the LEDs at four heights.
    cam, pts, uv = data
    thin = pts.copy()
    thin[:, 2] = -0.38 + 0.01 * np.random.default_rng(0).standard_normal(len(pts))
    uv_thin = cam.project(thin)
    keep = cam.in_image(uv_thin)
    rng = np.random.default_rng(1)
    with pytest.warns(DegenerateGeometryWarning, match="nearly coplanar"):
        poor = calibrate_tsai(thin[keep], uv_thin[keep] + rng.normal(0, 0.3, (keep.sum(), 2)), SIZE)
    good = calibrate_tsai(pts, uv + rng.normal(0, 0.3, uv.shape), SIZE)
    assert poor.std_by_name["f_px"] > 3 * good.std_by_name["f_px"]


def test_inconsistent_correspondences(data) -> None:
    _, pts, uv = data
    perm = np.random.default_rng(0).permutation(len(pts))
    with pytest.raises(ValueError, match="inconsistent"):
        calibrate_tsai(pts, uv[perm], SIZE)


def test_large_residuals_are_noted(data) -> None:
    _cam, pts, uv = data
    rng = np.random.default_rng(3)
    with pytest.warns(DegenerateGeometryWarning, match=r"residuals are large \(sigma"):
        res = calibrate_tsai(pts, uv + rng.normal(0, 8.0, uv.shape).clip(-30, 30), (400, 300))
    assert res.sigma_px > 5


def test_points_behind_the_camera(data) -> None:
    cam, pts, uv = data
    mirrored = 2 * cam.position - pts  # the same rays, behind the camera
    with pytest.raises(ValueError, match=r"\d+ of 70 points lie behind the camera"):
        calibrate_tsai(mirrored, uv, SIZE)
    with pytest.raises(ValueError, match=r"70 point\(s\) lie behind the camera, first in row 0"):
        cam.project(mirrored)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_nan_and_inf(data, bad) -> None:
    _, pts, uv = data
    p = pts.copy()
    p[12, 1] = bad
    with pytest.raises(
        ValueError, match=r"points_3d contains 1 NaN or inf value\(s\), first in row 12"
    ):
        calibrate_tsai(p, uv, SIZE)
    q = uv.copy()
    q[3, 0] = bad
    with pytest.raises(
        ValueError, match=r"pixels contains 1 NaN or inf value\(s\), first in row 3"
    ):
        calibrate_tsai(pts, q, SIZE)


def test_mismatched_shapes(data) -> None:
    _, pts, uv = data
    with pytest.raises(ValueError, match="points_3d has 70 rows but pixels has 69"):
        calibrate_tsai(pts, uv[:-1], SIZE)
    with pytest.raises(ValueError, match=r"points_3d must have shape \(N, 3\), got \(70, 2\)"):
        calibrate_tsai(pts[:, :2], uv, SIZE)
    with pytest.raises(ValueError, match=r"pixels must have shape \(N, 2\), got \(70, 3\)"):
        calibrate_tsai(pts, np.column_stack([uv, uv[:, 0]]), SIZE)


def test_image_size_that_does_not_contain_the_points(data) -> None:
    _, pts, uv = data
    n_out = int((uv[:, 0] > 199.5).sum())
    with pytest.raises(ValueError, match=rf"{n_out} pixel\(s\) lie outside the 200x240 image"):
        calibrate_tsai(pts, uv, (200, 240))
    with pytest.raises(ValueError, match="image_size must be two positive integers"):
        calibrate_tsai(pts, uv, (0, 240))
    with pytest.raises(ValueError, match=r"image_size must be \(width, height\)"):
        calibrate_tsai(pts, uv, "320x240")
