"""Polar <-> Cartesian conversions, their Jacobians, and the measurement record."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from twin.instruments.polar import (
    TotalStationMeasurement,
    cartesian2polar,
    polar2cartesian,
    polar2cartesian_jacobian,
)

distances = st.floats(1.3, 2200.0)
horizontals = st.floats(0.0, 2 * np.pi, exclude_max=True)
zeniths = st.floats(0.05, np.pi - 0.05)


def test_axes_follow_the_documented_convention():
    assert np.allclose(cartesian2polar([10.0, 0.0, 0.0]), [10.0, 0.0, np.pi / 2])
    assert np.allclose(cartesian2polar([0.0, 10.0, 0.0]), [10.0, np.pi / 2, np.pi / 2])
    assert np.allclose(cartesian2polar([0.0, -10.0, 0.0]), [10.0, 1.5 * np.pi, np.pi / 2])
    assert np.allclose(cartesian2polar([0.0, 0.0, 2.0]), [2.0, 0.0, 0.0])
    assert np.allclose(polar2cartesian([2.0, 0.3, np.pi]), [0.0, 0.0, -2.0])


@settings(max_examples=200, deadline=None)
@given(distances, horizontals, zeniths)
def test_polar_cartesian_round_trip(d, hz, v):
    polar = np.array([d, hz, v])
    back = cartesian2polar(polar2cartesian(polar))
    assert back[0] == pytest.approx(d, rel=1e-12)
    # hz near 2pi may come back as a value near 0: compare on the circle.
    assert np.angle(np.exp(1j * (back[1] - hz))) == pytest.approx(0.0, abs=1e-9)
    assert back[2] == pytest.approx(v, abs=1e-12)


@settings(max_examples=100, deadline=None)
@given(st.tuples(*[st.floats(-1e3, 1e3)] * 3).filter(lambda p: np.hypot(p[0], p[1]) > 1e-2))
def test_cartesian_polar_round_trip(point):
    p = np.array(point)
    np.testing.assert_allclose(polar2cartesian(cartesian2polar(p)), p, atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(distances, horizontals, zeniths)
def test_jacobian_matches_finite_differences(d, hz, v):
    polar = np.array([d, hz, v])
    jac = polar2cartesian_jacobian(polar)
    steps = np.array([1e-6 * d, 1e-7, 1e-7])
    fd = np.empty((3, 3))
    for k in range(3):
        e = np.zeros(3)
        e[k] = steps[k]
        fd[:, k] = (polar2cartesian(polar + e) - polar2cartesian(polar - e)) / (2 * steps[k])
    np.testing.assert_allclose(jac, fd, rtol=1e-6, atol=1e-6 * d)


def test_conversions_are_vectorised():
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(4, 5, 3)) * 10
    assert cartesian2polar(pts).shape == (4, 5, 3)
    assert polar2cartesian_jacobian(cartesian2polar(pts)).shape == (4, 5, 3, 3)


def test_bad_input():
    with pytest.raises(ValueError, match="instrument centre"):
        cartesian2polar([0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="NaN"):
        polar2cartesian([1.0, np.nan, 1.0])
    with pytest.raises(ValueError, match=r"shape \(\.\.\., 3\)"):
        cartesian2polar([1.0, 2.0])


def test_measurement_record():
    m = TotalStationMeasurement.from_polar([12.3456, 1.0, 1.5], timestamp=4.0)
    assert m.timestamp == 4.0
    np.testing.assert_allclose(m.to_cartesian(), polar2cartesian([12.3456, 1.0, 1.5]))
    with pytest.raises(AttributeError):
        m.distance = 3.0  # frozen
    with pytest.raises(ValueError, match="distance must be positive"):
        TotalStationMeasurement(0.0, -1.0, 0.0, 1.0)
    with pytest.raises(ValueError, match="horizontal angle"):
        TotalStationMeasurement(0.0, 1.0, 7.0, 1.0)
    with pytest.raises(ValueError, match="zenith angle"):
        TotalStationMeasurement(0.0, 1.0, 1.0, -0.1)
    with pytest.raises(ValueError, match="finite"):
        TotalStationMeasurement(np.nan, 1.0, 1.0, 1.0)
