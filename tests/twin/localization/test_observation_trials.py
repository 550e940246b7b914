"""Children's observations over trials: each trial equals :func:`observe_child`."""

import numpy as np
import pytest

from calib.rotation import rot_z
from twin.instruments.consistency import chi2_threshold
from twin.instruments.errors import InconsistentMarkerError
from twin.instruments.marker import MarkerAssembly
from twin.instruments.polar import TotalStationMeasurement, polar2cartesian
from twin.instruments.shot import measure_points
from twin.instruments.tilt import TiltReading
from twin.instruments.total_station import ARCSEC, InclinometerSpec, TotalStationSpec
from twin.localization.observation import ChildObservationBatch, observe_child, observe_child_batch

MARKER = MarkerAssembly()
SPEC, INCL = TotalStationSpec(), InclinometerSpec()
T = 40


def cube_shots(n, seed):
    """Levelled polar shots (n, 3, 3) at the cubes of n children 3-25 m away, with their
    (n, 3, 2) tilt readings, from a parent tilted by up to 60 arcsec."""
    rng = np.random.default_rng(seed)
    heading = rot_z(rng.uniform(-np.pi, np.pi, n))
    distance, bearing = rng.uniform(3, 25, n), rng.uniform(-np.pi, np.pi, n)
    x, y = distance * np.cos(bearing), distance * np.sin(bearing)
    floor = np.column_stack([x, y, np.full(n, -0.75)])
    cubes = np.einsum("tij,cj->tci", heading, MARKER.cubes_body) + floor[:, None]
    tilt = rng.uniform(-60 * ARCSEC, 60 * ARCSEC, (n, 1, 2))
    return measure_points(cubes, tilt[..., 0], tilt[..., 1], SPEC, INCL, rng)


def scalar_observation(polar, readings, child="c1", rate=None):
    shots = [
        TotalStationMeasurement.from_polar(polar[c], 5.0, TiltReading(5.0, *readings[c]))
        for c in range(3)
    ]
    return observe_child(child, shots, SPEC, INCL, false_alarm_rate=rate)


def test_each_trial_equals_observe_child():
    polar, readings = cube_shots(T, 1)
    batch = observe_child_batch("c1", polar, SPEC, INCL, timestamp=5.0)
    assert batch.point_level.shape == (T, 3)
    assert batch.covariance.shape == (T, 3, 3)
    assert batch.timestamp == 5.0
    for i in range(T):
        obs = scalar_observation(polar[i], readings[i])
        np.testing.assert_allclose(batch.point_level[i], obs.point_level, rtol=1e-12)
        np.testing.assert_allclose(batch.covariance[i], obs.covariance, rtol=1e-12, atol=1e-24)
        pose = batch.marker_pose
        np.testing.assert_allclose(pose.rotation[i], obs.marker_pose.rotation, atol=1e-12)
        np.testing.assert_allclose(pose.translation[i], obs.marker_pose.translation, rtol=1e-12)
        np.testing.assert_allclose(
            pose.covariance[i],
            obs.marker_pose.covariance,
            rtol=0,
            atol=1e-12 * np.abs(obs.marker_pose.covariance).max(),
        )
        assert pose.chi2[i] == pytest.approx(obs.marker_pose.chi2, rel=1e-12)
        assert pose.rms_residual[i] == pytest.approx(obs.marker_pose.rms_residual, rel=1e-12)
    # one trial back as a ChildObservation
    one = batch.trial(3)
    np.testing.assert_array_equal(one.point_level, batch.point_level[3])
    assert one.marker_pose.chi2 == batch.marker_pose.chi2[3]


def test_given_cartesian_points_are_used_and_default_to_the_polar_ones():
    polar, _ = cube_shots(5, 2)
    a = observe_child_batch("c1", polar, SPEC, INCL)
    b = observe_child_batch("c1", polar, SPEC, INCL, cubes_level=polar2cartesian(polar))
    np.testing.assert_array_equal(a.point_level, b.point_level)
    np.testing.assert_array_equal(a.marker_pose.chi2, b.marker_pose.chi2)


@pytest.mark.filterwarnings("ignore:Optimal rotation is not uniquely")
def test_a_wrong_prism_is_flagged_where_observe_child_raises():
    polar, readings = cube_shots(T, 3)
    polar[7, 0] = polar[7, 1]  # trial 7: the shot at cube 0 locked cube 1
    batch = observe_child_batch("c1", polar, SPEC, INCL)
    flags = batch.marker_inconsistent()
    threshold = chi2_threshold(3, 1e-4)
    for i in range(T):
        if flags[i]:
            with pytest.raises(InconsistentMarkerError):
                scalar_observation(polar[i], readings[i], rate=1e-4)
        else:
            scalar_observation(polar[i], readings[i], rate=1e-4)
    assert flags[7]
    assert np.count_nonzero(flags) == np.count_nonzero(batch.marker_pose.chi2 > threshold)
    assert not batch.marker_inconsistent(None).any()


def test_noise_free_shots_give_the_cube_centroids():
    rng = np.random.default_rng(4)
    floor = np.column_stack([rng.uniform(3, 20, 8), rng.uniform(-5, 5, 8), np.full(8, -0.75)])
    cubes = MARKER.cubes_body + floor[:, None]
    exact = TotalStationSpec.noiseless()
    polar, _ = measure_points(cubes, 0.0, 0.0, exact, InclinometerSpec(sigma=0.0), rng)
    batch = observe_child_batch("c1", polar, exact)
    np.testing.assert_allclose(batch.point_level, cubes.mean(axis=1), atol=1e-12)
    np.testing.assert_allclose(batch.marker_pose.translation, floor, atol=1e-12)


def test_bad_input():
    polar, _ = cube_shots(3, 5)
    with pytest.raises(ValueError, match=r"\(T, 3, 3\)"):
        observe_child_batch("c1", polar[0], SPEC, INCL)
    with pytest.raises(ValueError, match="cubes_level"):
        observe_child_batch("c1", polar, SPEC, INCL, cubes_level=np.zeros((2, 3, 3)))
    with pytest.raises(ValueError, match=r"point_level must be \(T, 3\)"):
        ChildObservationBatch("c1", np.zeros(3), np.zeros((1, 3, 3)))
    with pytest.raises(ValueError, match="NaN"):
        ChildObservationBatch("c1", np.full((2, 3), np.nan), np.zeros((2, 3, 3)))
    with pytest.raises(ValueError, match=r"covariance must be \(2, 3, 3\)"):
        ChildObservationBatch("c1", np.zeros((2, 3)), np.zeros((3, 3, 3)))
    negative = np.tile(-np.eye(3), (2, 1, 1))
    with pytest.raises(ValueError, match="positive semidefinite"):
        ChildObservationBatch("c1", np.zeros((2, 3)), negative)
