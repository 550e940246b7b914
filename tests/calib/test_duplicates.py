"""Exact duplicate rows are copies, not measurements: merged, counted, and noted."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from numpy.testing import assert_allclose, assert_array_equal

from calib import InputWarning, calibrate_exterior, calibrate_opencv, calibrate_tsai
from calib.duplicates import drop_duplicates, duplicate_rows
from calib.synthetic import led_points, paper_camera

N = 70


@pytest.fixture(scope="module")
def noisy():
    cam = paper_camera(1)
    rng = np.random.default_rng(31)
    pts = led_points(cam, N, rng)
    return cam, pts, cam.project(pts) + rng.normal(0.0, 0.3, (N, 2))


def doubled(a: np.ndarray) -> np.ndarray:
    """Every row twice, the copy right after its original."""
    return np.repeat(a, 2, axis=0)


@pytest.mark.parametrize("calibrate", [calibrate_tsai, calibrate_opencv], ids=["tsai", "opencv"])
def test_doubled_rows_give_the_result_of_the_rows(noisy, calibrate) -> None:
    cam, pts, uv = noisy
    once = calibrate(pts, uv, cam.image_size)
    with pytest.warns(InputWarning, match=f"{N} of the {2 * N} correspondences repeat"):
        twice = calibrate(doubled(pts), doubled(uv), cam.image_size)
    assert_allclose(twice.std, once.std, rtol=1e-12)
    assert_allclose(twice.values, once.values, rtol=1e-12)
    assert twice.n_points == once.n_points == N
    assert twice.dof == once.dof
    assert (twice.duplicates, twice.duplicates_kept) == (N, False)
    assert any("were merged" in note for note in twice.notes)
    assert once.duplicates == 0
    assert not any("repeat an earlier one" in note for note in once.notes)


def test_kept_duplicates_shrink_every_std(noisy) -> None:
    # Counted twice, the residual variance is |r|^2 * 2 / (4N - 11) and (J^T J)^-1 halves:
    # every std shrinks by sqrt((2N - 11) / (4N - 11)), close to 1/sqrt(2), for no new data.
    cam, pts, uv = noisy
    once = calibrate_tsai(pts, uv, cam.image_size)
    with pytest.warns(InputWarning, match="kept as independent measurements"):
        kept = calibrate_tsai(doubled(pts), doubled(uv), cam.image_size, keep_duplicates=True)
    assert kept.n_points == 2 * N
    assert (kept.duplicates, kept.duplicates_kept) == (N, True)
    assert_allclose(kept.std / once.std, np.sqrt((2 * N - 11) / (4 * N - 11)), rtol=1e-6)


def test_exterior_calibration_merges_duplicates(noisy) -> None:
    cam, pts, uv = noisy
    once = calibrate_exterior(pts, uv, cam)
    with pytest.warns(InputWarning, match="were merged"):
        twice = calibrate_exterior(doubled(pts), doubled(uv), cam)
    assert_allclose(twice.std, once.std, rtol=1e-12)


def test_copies_do_not_make_up_the_minimum_number_of_points(noisy) -> None:
    cam, pts, uv = noisy
    with pytest.raises(ValueError, match="needs at least 7 points, got 5"):
        calibrate_tsai(np.tile(pts[:5], (3, 1)), np.tile(uv[:5], (3, 1)), cam.image_size)


def test_a_repeated_point_with_another_pixel_is_not_a_duplicate(noisy) -> None:
    # Two detections of one LED position: the same x, y, z, pixels that differ by noise.
    cam, pts, uv = noisy
    again = uv + np.random.default_rng(0).normal(0.0, 0.3, uv.shape)
    res = calibrate_tsai(np.vstack([pts, pts]), np.vstack([uv, again]), cam.image_size)
    assert res.n_points == 2 * N
    assert res.duplicates == 0


@settings(max_examples=100, deadline=None)
@given(
    arrays(
        np.float64,
        st.tuples(st.integers(1, 12), st.just(5)),
        elements=st.sampled_from([0.0, -0.0, 1.0, 2.5]),
    )
)
def test_duplicate_rows_marks_every_repeat_but_the_first(rows) -> None:
    seen: set[tuple[float, ...]] = set()
    expected = []
    for r in rows.tolist():
        key = tuple(v + 0.0 for v in r)  # -0.0 and 0.0 are the same value
        expected.append(key in seen)
        seen.add(key)
    assert_array_equal(duplicate_rows(rows[:, :3], rows[:, 3:]), expected)
    p3, uv, count = drop_duplicates(rows[:, :3], rows[:, 3:])
    assert count == sum(expected)
    assert_array_equal(np.column_stack([p3, uv]), rows[~np.array(expected)])
