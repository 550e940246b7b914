"""Tsai's distortion and its exact inverse."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from calib.distortion import distort, distortion_scale, max_undistorted_radius, undistort

kappas = st.floats(-2e-6, 2e-6, allow_nan=False)
coords = st.floats(-250.0, 250.0, allow_nan=False)


@given(kappas, coords, coords)
def test_distort_inverts_undistort(kappa1: float, x: float, y: float) -> None:
    xy_d = np.array([[x, y]])
    if kappa1 < 0 and np.hypot(x, y) ** 2 >= 1.0 / (3.0 * -kappa1):
        return  # beyond the fold of the lens: not a point an image can contain
    xy_u = undistort(xy_d, kappa1)
    assert_allclose(distort(xy_u, kappa1), xy_d, rtol=1e-12, atol=1e-10)


@given(kappas, coords, coords)
def test_undistort_inverts_distort(kappa1: float, x: float, y: float) -> None:
    xy_u = np.array([[x, y]])
    xy_d = distort(xy_u, kappa1)
    if np.isnan(xy_d).any():
        assert np.hypot(x, y) >= max_undistorted_radius(kappa1) * (1 - 1e-12)
        return
    assert_allclose(undistort(xy_d, kappa1), xy_u, rtol=1e-12, atol=1e-10)


def test_scale_is_continuous_across_branches() -> None:
    # The series (|t| < 1e-3) and the closed forms must agree at the switch.
    t = np.array([-1e-3 - 1e-12, -1e-3 + 1e-12, 1e-3 - 1e-12, 1e-3 + 1e-12])
    s = distortion_scale(t)
    assert_allclose(t * s**3 + s - 1.0, 0.0, atol=1e-13)
    assert_allclose(s[0], s[1], rtol=1e-10)
    assert_allclose(s[2], s[3], rtol=1e-10)


def test_scale_solves_the_cubic_exactly() -> None:
    t = np.concatenate([-np.logspace(-12, np.log10(4 / 27 * 0.999), 200), np.logspace(-12, 3, 200)])
    s = distortion_scale(t)
    assert_allclose(t * s**3 + s - 1.0, 0.0, atol=1e-13)
    # The physical root: positive and continuous with s = 1 at t = 0.
    assert (s > 0).all()
    assert (np.diff(s[200:]) <= 0).all()


def test_beyond_the_fold_is_nan() -> None:
    k = -1e-6
    r_max = max_undistorted_radius(k)
    out = distort(np.array([[r_max * 1.01, 0.0], [r_max * 0.99, 0.0]]), k)
    assert np.isnan(out[0]).all()
    assert np.isfinite(out[1]).all()
    assert max_undistorted_radius(1e-6) == np.inf
