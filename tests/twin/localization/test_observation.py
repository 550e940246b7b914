"""A child's observation from the three shots at its cubes."""

import numpy as np
import pytest

from twin.instruments.marker import MarkerAssembly
from twin.instruments.noise import cartesian_covariance
from twin.instruments.shot import simulate_shot
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec
from twin.localization.observation import observe_child, reference_from_cubes

MARKER = MarkerAssembly()


def shots_at(cubes, spec, seed):
    rng = np.random.default_rng(seed)
    return [
        simulate_shot(cubes, cube, spec, rng, inclinometer=InclinometerSpec(), timestamp=float(i))
        for i, cube in enumerate(cubes)
    ]


def test_noise_free_observation_is_the_cube_centroid():
    cubes = MARKER.cubes_body + np.array([6.0, 2.0, -0.75])
    exact = TotalStationSpec.noiseless()
    rng = np.random.default_rng(0)
    exact_incl = InclinometerSpec(sigma=0.0)
    shots = [
        simulate_shot(cubes, c, exact, rng, inclinometer=exact_incl, timestamp=t)
        for t, c in enumerate(cubes)
    ]
    assert [s.prism_index for s in shots] == [0, 1, 2]
    obs = observe_child("c1", [s.measurement for s in shots], exact, exact_incl)
    np.testing.assert_allclose(obs.point_level, cubes.mean(axis=0), atol=1e-12)
    assert obs.timestamp == 2.0
    assert len(obs.shots) == 3


def test_observation_covariance_and_vectorised_path_agree():
    spec, incl = TotalStationSpec(), InclinometerSpec()
    cubes = MARKER.cubes_body + np.array([9.0, -3.0, -0.75])
    meas = [s.measurement for s in shots_at(cubes, spec, 4)]
    obs = observe_child("c1", meas, spec, incl)
    polar = np.array([m.polar for m in meas])
    cart = np.array([m.to_cartesian() for m in meas])
    point, cov = reference_from_cubes(cart, polar, spec, incl)
    np.testing.assert_allclose(obs.point_level, point)
    np.testing.assert_allclose(obs.covariance, cov, rtol=1e-12, atol=1e-20)
    expected = cartesian_covariance(polar, spec, incl).sum(axis=0) / 9
    np.testing.assert_allclose(obs.covariance, expected, rtol=1e-12, atol=1e-20)
    assert np.linalg.norm(obs.point_level - cubes.mean(axis=0)) < 0.01


def test_observation_needs_three_shots():
    spec = TotalStationSpec()
    cubes = MARKER.cubes_body + np.array([9.0, -3.0, -0.75])
    meas = [s.measurement for s in shots_at(cubes, spec, 1)]
    with pytest.raises(ValueError, match="needs 3 cube shots, got 2"):
        observe_child("c1", meas[:2], spec)
