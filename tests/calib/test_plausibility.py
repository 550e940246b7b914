"""Magnitudes no real camera produces are noted, with the likely mistake; real ones are not.

A scene read in the wrong unit is the true scene scaled by 1000 or 1/1000, camera included:
the checks are run on the true camera and points scaled so, over the band of ranges that
:mod:`calib.plausibility` argues every wrong reading is caught in (1 m to 50 m).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from calib import InputWarning, calibrate_opencv, calibrate_tsai
from calib.io import read_points_csv
from calib.plausibility import check_magnitudes, field_of_view_deg
from calib.synthetic import paper_camera, points_in_view

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "camera1_points.csv"


def scene(range_m: float):
    """Camera 1 and 200 points at 0.8-1.25 times ``range_m`` in front of it."""
    cam = paper_camera(1)
    pts = points_in_view(cam, 200, np.random.default_rng(5), depth_m=(0.8 * range_m, range_m))
    return cam, pts


def causes(cam, pts, scale: float = 1.0, **changes) -> list[str]:
    args = dict(f_px=cam.f, sx=cam.sx, image_size=cam.image_size, kappa1=cam.kappa1) | changes
    found = check_magnitudes(cam.position * scale, points_3d=pts * scale, **args)
    return [f.cause for f in found]


@pytest.mark.parametrize("range_m", [1.25, 3.0, 15.0, 50.0])
def test_every_wrong_unit_is_caught_in_the_band_and_no_right_one(range_m) -> None:
    cam, pts = scene(range_m)
    assert causes(cam, pts) == []
    assert causes(cam, pts, 1e3) == ["units-too-large"]  # millimetres read as metres
    assert causes(cam, pts, 1e-3) == ["units-too-small"]  # metres read as millimetres


def test_the_range_bounds() -> None:
    cam, pts = scene(15.0)
    dist = np.median(np.linalg.norm(pts - cam.position, axis=1))
    assert causes(cam, pts, 999.0 / dist) == []
    assert causes(cam, pts, 1001.0 / dist) == ["units-too-large"]
    assert causes(cam, pts, 0.051 / dist) == []
    assert causes(cam, pts, 0.049 / dist) == ["units-too-small"]


def test_a_focal_length_far_outside_the_image_size() -> None:
    cam, pts = scene(10.0)
    half_diagonal = 200.0  # 320 x 240
    assert field_of_view_deg(half_diagonal, 1.0, (320, 240)) == pytest.approx(90.0)
    wide = half_diagonal / np.tan(np.radians(80.0))  # 160 deg
    narrow = half_diagonal / np.tan(np.radians(0.25))  # 0.5 deg
    assert causes(cam, pts, f_px=1.01 * wide) == []
    assert causes(cam, pts, f_px=0.99 * wide) == ["image"]
    assert causes(cam, pts, f_px=0.99 * narrow) == []
    assert causes(cam, pts, f_px=1.01 * narrow) == ["image"]


def test_a_distortion_no_lens_has() -> None:
    cam, pts = scene(10.0)
    corner_r2 = 160.0**2 + 120.0**2
    assert causes(cam, pts, kappa1=1.9 / corner_r2) == []
    assert causes(cam, pts, kappa1=-2.1 / corner_r2) == ["image"]
    assert causes(cam, pts, kappa1=None) == []


@pytest.mark.parametrize("calibrate", [calibrate_tsai, calibrate_opencv], ids=["tsai", "opencv"])
def test_the_example_read_in_metres_is_noted(calibrate) -> None:
    # The shipped example is in millimetres: read in metres it calibrates, 5 km away.
    pts, uv = read_points_csv(EXAMPLE, "m")
    with pytest.warns(
        InputWarning, match=r"km from its points .* were the coordinates in millimetres"
    ):
        res = calibrate(pts, uv, (320, 240))
    assert [f.cause for f in res.implausible] == ["units-too-large"]
    assert res.implausible[0].note in res.notes
    pts, uv = read_points_csv(EXAMPLE, "mm")
    assert calibrate(pts, uv, (320, 240)).implausible == ()
