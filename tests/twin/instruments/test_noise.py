"""The GTS-820A noise model (Table I): standard deviations, quantisation, covariance."""

import numpy as np
import pytest

from twin.instruments.noise import (
    cartesian_covariance,
    distance_sigma,
    normalise_polar,
    polar_covariance,
    quantise_polar,
)
from twin.instruments.polar import cartesian2polar, polar2cartesian
from twin.instruments.shot import measure_points
from twin.instruments.total_station import ARCSEC, InclinometerSpec, TotalStationSpec

SPEC = TotalStationSpec()
N = 10_000


def on_grid(values, resolution):
    k = values / resolution
    return np.all(np.abs(k - np.round(k)) < 1e-6)


def smallest_gap(values):
    """Smallest nonzero difference between the sorted unique values."""
    gaps = np.diff(np.unique(values))
    return gaps[gaps > 0].min()


def test_spec_defaults_are_table_one():
    assert SPEC.distance_sigma(10.0) == pytest.approx(2.02e-3)
    assert SPEC.distance_sigma(1000.0) == pytest.approx(4.0e-3)
    assert SPEC.angle_sigma == pytest.approx(5 * np.pi / 180 / 3600)
    assert SPEC.distance_resolution == 0.2e-3
    assert SPEC.angle_resolution == pytest.approx(ARCSEC)
    assert (SPEC.range_min, SPEC.range_max) == (1.3, 2200.0)
    np.testing.assert_allclose(distance_sigma([10.0, 1000.0], SPEC), [2.02e-3, 4.0e-3])


@pytest.mark.parametrize("distance", [10.0, 1000.0])
def test_simulated_shots_have_the_specified_spread_and_grid(distance):
    rng = np.random.default_rng(42)
    # Random directions, all at the same distance, in a level instrument.
    hz = rng.uniform(0, 2 * np.pi, N)
    v = rng.uniform(np.radians(60), np.radians(120), N)
    true = np.stack([np.full(N, distance), hz, v], axis=-1)
    points = polar2cartesian(true)
    exact_incl = InclinometerSpec(sigma=0.0)
    measured, _ = measure_points(points, 0.0, 0.0, SPEC, exact_incl, rng)

    err = measured - true
    err[:, 1] = np.angle(np.exp(1j * err[:, 1]))
    std = err.std(axis=0)
    assert std[0] == pytest.approx(SPEC.distance_sigma(distance), rel=0.05)
    assert std[1] == pytest.approx(5 * ARCSEC, rel=0.05)
    assert std[2] == pytest.approx(5 * ARCSEC, rel=0.05)
    assert np.abs(err.mean(axis=0)[0]) < 4 * std[0] / np.sqrt(N)  # unbiased
    # Output resolution: 0.2 mm and 1 arc-second grids.
    assert on_grid(measured[:, 0], 0.2e-3)
    assert on_grid(measured[:, 1], ARCSEC)
    assert on_grid(measured[:, 2], ARCSEC)
    # ... and the grid is really used, not finer values that happen to round.
    assert len(np.unique(np.round(measured[:, 0] / 0.2e-3))) > 20
    # ... and it is not a coarser grid (0.4 mm or 3" values are also multiples of 0.2 mm
    # and 1"): neighbouring reported values are exactly one resolution step apart.
    assert smallest_gap(measured[:, 0]) == pytest.approx(0.2e-3, rel=1e-6)
    assert smallest_gap(measured[:, 1]) == pytest.approx(ARCSEC, rel=1e-6)
    assert smallest_gap(measured[:, 2]) == pytest.approx(ARCSEC, rel=1e-6)


def test_quantise_rounds_to_nearest_grid_point():
    q = quantise_polar([[10.00011, 0.5 * ARCSEC + 1e-9, 3.4 * ARCSEC]], SPEC)[0]
    assert q[0] == pytest.approx(10.0002)
    assert q[1] == pytest.approx(ARCSEC)
    assert q[2] == pytest.approx(3 * ARCSEC)
    # hz just below 2 pi rounds to 0, not to 2 pi.
    assert quantise_polar([[5.0, 2 * np.pi - 0.2 * ARCSEC, 1.0]], SPEC)[0, 1] == 0.0
    exact = TotalStationSpec.noiseless()
    np.testing.assert_array_equal(
        quantise_polar([[1.23456789, 1.0, 1.0]], exact), [[1.23456789, 1.0, 1.0]]
    )


def test_normalise_keeps_the_point():
    raw = np.array([[5.0, -0.3, 1.0], [5.0, 7.0, -0.2], [5.0, 1.0, np.pi + 0.1]])
    norm = normalise_polar(raw)
    assert np.all((norm[:, 1] >= 0) & (norm[:, 1] < 2 * np.pi))
    assert np.all((norm[:, 2] >= 0) & (norm[:, 2] <= np.pi))
    np.testing.assert_allclose(polar2cartesian(norm), polar2cartesian(raw), atol=1e-12)


def test_polar_covariance_includes_rounding():
    cov = polar_covariance([10.0, 0.0, 1.0], SPEC)
    assert cov[0, 0] == pytest.approx(SPEC.distance_sigma(10.0) ** 2 + 0.2e-3**2 / 12)
    assert cov[1, 1] == pytest.approx((25 + 1 / 12) * ARCSEC**2)
    no_q = polar_covariance([10.0, 0.0, 1.0], SPEC, quantisation=False)
    assert no_q[0, 0] == pytest.approx(SPEC.distance_sigma(10.0) ** 2)


def test_cartesian_covariance_matches_simulation():
    rng = np.random.default_rng(7)
    point = np.array([8.0, 5.0, 0.7])
    incl = InclinometerSpec(sigma=20 * ARCSEC)  # large, so its contribution is visible
    roll, pitch = 40 * ARCSEC, -25 * ARCSEC
    from twin.instruments.tilt import tilt_rotation

    instrument = tilt_rotation(roll, pitch).T @ point
    measured, _ = measure_points(np.tile(instrument, (N, 1)), roll, pitch, SPEC, incl, rng)
    xyz = polar2cartesian(measured)
    sample = np.cov(xyz.T)
    predicted = cartesian_covariance(cartesian2polar(point), SPEC, incl)
    # Compare through the whitened sample covariance: identity within sampling error.
    lw = np.linalg.cholesky(np.linalg.inv(predicted))
    np.testing.assert_allclose(lw.T @ sample @ lw, np.eye(3), atol=0.06)
    assert np.all(np.abs(xyz.mean(axis=0) - point) < 4 * np.sqrt(np.diag(predicted) / N))
