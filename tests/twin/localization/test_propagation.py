"""World positions of measured points and LEDs, with the parent's uncertainty."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from twin.instruments.marker import MarkerAssembly
from twin.instruments.marker_pose import fit_marker_pose, led_positions
from twin.localization.planar import level2world, world2level
from twin.localization.pose import ParentPose
from twin.localization.propagation import level2world_with_covariance

MARKER = MarkerAssembly()


def test_noise_free_mapping_is_paper_eq_1():
    pose = ParentPose(0.7, np.array([3.0, -1.0, 0.2]))
    pts = np.array([[5.0, 1.0, 0.4], [8.0, -2.0, 0.6]])
    world, cov = level2world_with_covariance(pose, pts)
    np.testing.assert_allclose(world, level2world(pts, 0.7, [3.0, -1.0, 0.2]))
    np.testing.assert_allclose(world2level(world, 0.7, [3.0, -1.0, 0.2]), pts, atol=1e-12)
    assert np.all(cov == 0)
    with pytest.raises(ValueError, match="points_level"):
        level2world_with_covariance(pose, [[np.nan, 0.0, 0.0]])
    with pytest.raises(ValueError, match="cov_level"):
        level2world_with_covariance(pose, pts, np.eye(3))


def test_led_world_covariance_includes_the_parent():
    rng = np.random.default_rng(21)
    true_pose = ParentPose(0.3, np.array([40.0, 2.0, 0.0]))
    p_cov = np.diag([(20e-6) ** 2, 4e-6, 9e-6, 1e-6])  # 20 urad yaw, 2-3 mm position
    body2world = Rotation.from_euler("z", 1.1).as_matrix()
    child = np.array([52.0, 6.0, -0.75])
    cubes_world = MARKER.cubes_body @ body2world.T + child
    leds_true = MARKER.leds_body @ body2world.T + child
    cubes_level = world2level(cubes_world, true_pose.yaw, true_pose.translation)
    sigma = 1e-3
    cov_level = np.tile(np.eye(3) * sigma**2, (3, 1, 1))
    lp = np.linalg.cholesky(p_cov)
    n = 2000
    nees = np.empty(n)
    for i in range(n):
        v = true_pose.vector + lp @ rng.standard_normal(4)
        est = ParentPose(v[0], v[1:], p_cov)
        measured = cubes_level + sigma * rng.standard_normal((3, 3))
        world, cov = level2world_with_covariance(est, measured, cov_level)
        assert cov.shape == (9, 9)
        leds, led_cov = led_positions(fit_marker_pose(world, MARKER, cov), MARKER)
        e = leds[0] - leds_true[0]
        nees[i] = e @ np.linalg.solve(led_cov[:3, :3], e)
    assert nees.mean() == pytest.approx(3.0, abs=0.25)  # standard error 0.055
