"""Tilt compensation: rotation convention, levelling, range, noise."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from twin.instruments.errors import FailureReason, TiltOutOfRangeError
from twin.instruments.tilt import (
    TiltReading,
    level_points,
    read_inclinometer,
    tilt_covariance,
    tilt_from_orientation,
    tilt_rotation,
)
from twin.instruments.total_station import ARCSEC, InclinometerSpec

angles = st.floats(-0.5, 0.5)


@settings(max_examples=50, deadline=None)
@given(angles, angles)
def test_tilt_rotation_convention(roll, pitch):
    expected = Rotation.from_euler("xy", [roll, pitch]).as_matrix()  # x first, then fixed y
    np.testing.assert_allclose(tilt_rotation(roll, pitch), expected, atol=1e-12)
    # the instrument's x-axis stays in the level x-z plane: levelling keeps the heading
    assert tilt_rotation(roll, pitch)[1, 0] == pytest.approx(0.0, abs=1e-15)


@settings(max_examples=50, deadline=None)
@given(st.floats(-3.0, 3.0), angles, angles)
def test_tilt_from_orientation_round_trip(yaw, roll, pitch):
    orientation = Rotation.from_euler("z", yaw).as_matrix() @ tilt_rotation(roll, pitch)
    r, p = tilt_from_orientation(orientation)
    assert (r, p) == (pytest.approx(roll, abs=1e-9), pytest.approx(pitch, abs=1e-9))


def test_levelling_recovers_level_coordinates():
    rng = np.random.default_rng(1)
    level = rng.normal(size=(6, 3)) * 20
    roll, pitch = 100 * ARCSEC, -150 * ARCSEC
    instrument = level @ tilt_rotation(roll, pitch)  # R^T applied to each row
    np.testing.assert_allclose(level_points(instrument, roll, pitch), level, atol=1e-12)


def test_reading_noise_and_range():
    spec = InclinometerSpec()
    rng = np.random.default_rng(5)
    readings = np.array(
        [
            [r.roll, r.pitch]
            for r in (read_inclinometer(1e-4, -2e-4, spec, rng) for _ in range(4000))
        ]
    )
    assert readings.std(axis=0) == pytest.approx([ARCSEC, ARCSEC], rel=0.05)
    assert readings.mean(axis=0) == pytest.approx([1e-4, -2e-4], abs=4 * ARCSEC / np.sqrt(4000))
    with pytest.raises(TiltOutOfRangeError) as info:
        read_inclinometer(0.0, 200 * ARCSEC, spec, rng)
    assert info.value.reason is FailureReason.TILT_OUT_OF_RANGE
    with pytest.raises(ValueError, match="finite"):
        read_inclinometer(np.nan, 0.0, spec, rng)
    with pytest.raises(ValueError, match="finite"):
        TiltReading(0.0, np.nan, 0.0)


def test_tilt_covariance_matches_perturbation():
    spec = InclinometerSpec(sigma=1e-3)
    rng = np.random.default_rng(2)
    point = np.array([10.0, -4.0, 2.0])
    d = spec.sigma * rng.standard_normal((20000, 2))
    moved = np.einsum("nij,j->ni", tilt_rotation(d[:, 0], d[:, 1]), point)
    sample = np.cov(moved.T)
    predicted = tilt_covariance(point, spec)
    assert np.linalg.matrix_rank(predicted, tol=1e-12) == 2
    np.testing.assert_allclose(sample, predicted, atol=0.05 * np.max(predicted))


@pytest.mark.parametrize(
    ("tilt_arcsec", "accepted"), [(179.9, True), (-179.9, True), (180.1, False), (-180.1, False)]
)
def test_working_range_edge(tilt_arcsec, accepted):
    # An exact sensor, just inside and just outside the 180" (3') working range, each axis.
    spec = InclinometerSpec(sigma=0.0)
    rng = np.random.default_rng(0)
    for roll, pitch in ((tilt_arcsec, 0.0), (0.0, tilt_arcsec)):
        if accepted:
            reading = read_inclinometer(roll * ARCSEC, pitch * ARCSEC, spec, rng)
            assert (reading.roll, reading.pitch) == (roll * ARCSEC, pitch * ARCSEC)
        else:
            with pytest.raises(TiltOutOfRangeError):
                read_inclinometer(roll * ARCSEC, pitch * ARCSEC, spec, rng)
