"""Marker poses over trials: each trial equals the fit of that trial alone, bit for bit, and
the truth is recovered."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from twin.instruments.marker import MarkerAssembly
from twin.instruments.marker_pose import (
    cube_centroid_batch,
    fit_marker_pose,
    fit_marker_pose_batch,
    kabsch_rotation,
    led_positions,
    led_positions_batch,
)
from twin.instruments.noise import cartesian_covariance
from twin.instruments.polar import polar2cartesian
from twin.instruments.shot import measure_points
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec

MARKER = MarkerAssembly()
T = 60
RTOL = 1e-12


def poses(n, seed):
    """(n, 3, 3) random rotations (any attitude) and (n, 3) translations up to 30 m."""
    rng = np.random.default_rng(seed)
    return Rotation.random(n, random_state=seed).as_matrix(), rng.uniform(-30, 30, (n, 3))


def measured(n, seed):
    """Noisy cubes of n assemblies, their polar shots and per-cube covariances."""
    spec, incl = TotalStationSpec(), InclinometerSpec()
    rot, t = poses(n, seed)
    cubes = np.einsum("tij,cj->tci", rot, MARKER.cubes_body) + t[:, None, :]
    polar, _ = measure_points(cubes, 0.0, 0.0, spec, incl, np.random.default_rng(seed + 1))
    return polar2cartesian(polar), cartesian_covariance(polar, spec, incl)


def close(actual, expected, rtol=RTOL):
    """Equal to ``rtol`` relative to the largest entry of ``expected``."""
    scale = np.max(np.abs(expected))
    np.testing.assert_allclose(actual, expected, rtol=0, atol=rtol * scale)


def test_each_trial_equals_the_scalar_fit():
    cubes, cov = measured(T, 1)
    batch = fit_marker_pose_batch(cubes, MARKER, cov)
    leds, leds_cov = led_positions_batch(batch, MARKER)
    point, point_cov = cube_centroid_batch(cubes, cov)
    assert batch.covariance.shape == (T, 6, 6)
    assert leds.shape == (T, 4, 3)
    assert leds_cov.shape == (T, 12, 12)
    for i in range(T):
        pose = fit_marker_pose(cubes[i], MARKER, cov[i])
        for name in ("rotation", "translation", "covariance", "rms_residual", "chi2"):
            np.testing.assert_array_equal(getattr(batch, name)[i], getattr(pose, name))
        assert isinstance(pose.rms_residual, float)
        assert isinstance(pose.chi2, float)
        one_leds, one_cov = led_positions(pose, MARKER)
        np.testing.assert_array_equal(leds[i], one_leds)
        np.testing.assert_array_equal(leds_cov[i], one_cov)
        one_point, one_point_cov = cube_centroid_batch(cubes[i], cov[i])
        np.testing.assert_array_equal(point[i], one_point)
        np.testing.assert_array_equal(point_cov[i], one_point_cov)


def test_batched_kabsch_gives_scipys_rotation():
    # Any attitude, including turns near pi. Three cubes span a plane, so B has rank 2 and
    # the sign of its third singular vectors is arbitrary: the sign fix acts often.
    cubes, _ = measured(200, 2)
    flipped = Rotation.from_rotvec([[np.pi - 1e-9, 0, 0], [0, 0, np.pi]]).as_matrix()
    cubes = np.concatenate([cubes, np.einsum("tij,cj->tci", flipped, MARKER.cubes_body)])
    body = MARKER.cubes_body - MARKER.cubes_body.mean(axis=0)
    centred = cubes - cubes.mean(axis=-2, keepdims=True)
    rot = kabsch_rotation(centred, body)
    for i in range(len(cubes)):
        expected = Rotation.align_vectors(centred[i], body)[0].as_matrix()
        np.testing.assert_allclose(rot[i], expected, rtol=0, atol=1e-14)
    np.testing.assert_allclose(
        rot @ np.swapaxes(rot, -1, -2), np.broadcast_to(np.eye(3), rot.shape), atol=1e-15
    )
    np.testing.assert_allclose(np.linalg.det(rot), 1.0, atol=1e-15)


def test_noise_free_cubes_give_the_exact_poses_and_leds():
    rot, t = poses(T, 3)
    cubes = np.einsum("tij,cj->tci", rot, MARKER.cubes_body) + t[:, None, :]
    batch = fit_marker_pose_batch(cubes, MARKER)
    np.testing.assert_allclose(batch.rotation, rot, atol=1e-12)
    np.testing.assert_allclose(batch.translation, t, atol=1e-12)
    assert np.all(batch.rms_residual < 1e-12)
    assert batch.chi2 is None
    assert np.all(batch.covariance == 0)
    leds, cov = led_positions_batch(batch, MARKER)
    np.testing.assert_allclose(leds, np.einsum("tij,kj->tki", rot, MARKER.leds_body) + t[:, None])
    assert np.all(cov == 0)


def test_a_joint_covariance_gives_the_same_as_per_cube_blocks():
    cubes, cov = measured(5, 4)
    joint = np.zeros((5, 9, 9))
    for i in range(3):
        joint[:, 3 * i : 3 * i + 3, 3 * i : 3 * i + 3] = cov[:, i]
    a = fit_marker_pose_batch(cubes, MARKER, cov)
    b = fit_marker_pose_batch(cubes, MARKER, joint)
    np.testing.assert_array_equal(a.covariance, b.covariance)
    np.testing.assert_array_equal(a.chi2, b.chi2)
    pose = fit_marker_pose(cubes[2], MARKER, joint[2])
    close(b.covariance[2], pose.covariance)


def test_a_trial_does_not_depend_on_its_batch():
    cubes, cov = measured(T, 5)
    batch = fit_marker_pose_batch(cubes, MARKER, cov)
    leds, leds_cov = led_positions_batch(batch, MARKER)
    for i in (0, 17, T - 1):
        one = fit_marker_pose_batch(cubes[i : i + 1], MARKER, cov[i : i + 1])
        for name in ("rotation", "translation", "covariance", "rms_residual", "chi2"):
            np.testing.assert_array_equal(getattr(one, name)[0], getattr(batch, name)[i])
        one_leds, one_cov = led_positions_batch(one, MARKER)
        np.testing.assert_array_equal(one_leds[0], leds[i])
        np.testing.assert_array_equal(one_cov[0], leds_cov[i])


def test_trial_axes_of_any_shape_and_one_trial_as_a_marker_pose():
    cubes, cov = measured(6, 6)
    flat = fit_marker_pose_batch(cubes, MARKER, cov)
    grid = fit_marker_pose_batch(cubes.reshape(2, 3, 3, 3), MARKER, cov.reshape(2, 3, 3, 3, 3))
    assert grid.batch_shape == (2, 3)
    np.testing.assert_array_equal(grid.covariance.reshape(6, 6, 6), flat.covariance)
    pose = flat.trial(4)
    assert pose.chi2 == flat.chi2[4]
    leds = flat.transform(MARKER.leds_body)
    np.testing.assert_array_equal(pose.transform(MARKER.leds_body), leds[4])


def test_a_wrong_prism_has_a_large_chi2_in_its_trial_only():
    cubes, cov = measured(4, 7)
    cubes[2, 0] = cubes[2, 1]  # trial 2: the shot at cube 0 locked cube 1
    chi2 = fit_marker_pose_batch(cubes, MARKER, cov).chi2
    assert chi2[2] > 1e4
    assert np.all(np.delete(chi2, 2) < 30)


@pytest.mark.parametrize(
    ("cubes", "cov", "match"),
    [
        (np.zeros((4, 3, 2)), None, "shape"),
        (np.full((4, 3, 3), np.nan), None, "NaN"),
        (np.ones((4, 3, 3)), np.zeros((4, 9, 8)), "cube covariance must have shape"),
        (np.ones((4, 3, 3)), np.full((4, 9, 9), np.nan), "NaN"),
        (np.ones((4, 3, 3)), np.triu(np.ones((4, 9, 9))), "symmetric"),
    ],
)
def test_bad_input(cubes, cov, match):
    with pytest.raises(ValueError, match=match):
        fit_marker_pose_batch(cubes, MARKER, cov)


@pytest.mark.parametrize(
    ("cubes", "cov", "match"),
    [
        (np.zeros((4, 3, 3)), None, r"shape \(3, 3\)"),
        (np.full((3, 3), np.nan), None, r"NaN or inf: \[\[nan"),
        (np.ones((3, 3)), np.zeros((9, 8)), r"\(3, 3, 3\) or \(9, 9\)"),
        (np.ones((3, 3)), np.triu(np.ones((9, 9))), "symmetric"),
    ],
)
def test_one_fit_raises_where_the_trials_are_flagged(cubes, cov, match):
    with pytest.raises(ValueError, match=match):
        fit_marker_pose(cubes, MARKER, cov)
