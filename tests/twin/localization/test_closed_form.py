"""The paper's closed form (eq. 2): exact recovery, Jacobian, bad input."""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from tests.twin.localization.helpers import iso_cov, measure_from
from twin.localization.closed_form import (
    closed_form_jacobians_batch,
    closed_form_pose_batch,
    solve_closed_form,
)
from twin.localization.planar import level2world

coords = st.floats(-50.0, 50.0)
point = st.tuples(coords, coords, st.floats(-2.0, 2.0))


@settings(max_examples=100, deadline=None)
@given(st.floats(-np.pi, np.pi, exclude_max=True), point, point, point)
def test_noise_free_recovers_the_exact_pose(yaw, translation, c1, c2):
    world = np.array([c1, c2])
    t = np.array(translation)
    assume(np.hypot(*(world[0, :2] - world[1, :2])) >= 0.1)
    level = measure_from(yaw, t, world)
    sol = solve_closed_form(world, level)
    assert np.angle(np.exp(1j * (sol.pose.yaw - yaw))) == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(sol.pose.translation, t, atol=1e-8)
    np.testing.assert_allclose(
        level2world(level, sol.pose.yaw, sol.pose.translation), world, atol=1e-8
    )


def test_children_on_a_line_through_the_parent_are_fine():
    # The paper's Fig. 6: all three robots in series. Two distinct horizontal points fix a
    # planar rigid motion, whatever the parent's position.
    yaw, t = 0.3, np.array([2.0, 1.0, 0.0])
    world = level2world(np.array([[4.0, 0.0, 0.6], [9.0, 0.0, 0.6]]), yaw, t)
    sol = solve_closed_form(world, measure_from(yaw, t, world))
    assert sol.pose.yaw == pytest.approx(yaw)
    np.testing.assert_allclose(sol.pose.translation, t, atol=1e-12)


def test_jacobians_match_finite_differences():
    rng = np.random.default_rng(4)
    world = rng.normal(size=(2, 3)) * 8
    level = measure_from(0.8, np.array([1.0, -3.0, 0.2]), world) + rng.normal(size=(2, 3)) * 0.01
    yaw, _ = closed_form_pose_batch(world[None], level[None])
    g_world, g_level = (g[0] for g in closed_form_jacobians_batch(world[None], level[None], yaw))
    h = 1e-6

    def pose(w, m):
        y, t = closed_form_pose_batch(w[None], m[None])
        return np.concatenate([y, t[0]])

    for k in range(6):
        e = np.zeros(6)
        e[k] = h
        e = e.reshape(2, 3)
        fd_w = (pose(world + e, level) - pose(world - e, level)) / (2 * h)
        fd_m = (pose(world, level + e) - pose(world, level - e)) / (2 * h)
        np.testing.assert_allclose(g_world[:, k], fd_w, atol=1e-7)
        np.testing.assert_allclose(g_level[:, k], fd_m, atol=1e-7)


def test_covariance_matches_monte_carlo():
    rng = np.random.default_rng(8)
    yaw, t = 0.4, np.array([5.0, 2.0, 0.0])
    world = np.array([[12.0, 3.0, 0.6], [15.0, -2.0, 0.5]])
    level = measure_from(yaw, t, world)
    cov_w = np.diag([1, 2, 3, 4, 1, 2]) * 1e-6
    cov_m = iso_cov(2, 2e-3)
    n = 4000
    w = world + rng.multivariate_normal(np.zeros(6), cov_w, size=n).reshape(n, 2, 3)
    m = level + rng.normal(size=(n, 2, 3)) * 2e-3
    y, tt = closed_form_pose_batch(w, m)
    poses = np.column_stack([y, tt])
    predicted = solve_closed_form(world, level, cov_w, cov_m).pose.covariance
    sample = np.cov(poses.T)
    np.testing.assert_allclose(np.sqrt(np.diag(sample)), np.sqrt(np.diag(predicted)), rtol=0.05)


def test_bad_input():
    w = np.array([[10.0, 0.0, 0.0], [12.0, 1.0, 0.0]])
    with pytest.raises(ValueError, match="at least two children"):
        solve_closed_form(w[:1], w[:1])
    with pytest.raises(ValueError, match="exactly two children"):
        solve_closed_form(np.vstack([w, [[5.0, 5.0, 0.0]]]), np.vstack([w, [[5.0, 5.0, 0.0]]]))
    bad = w.copy()
    bad[1, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        solve_closed_form(bad, w)
    with pytest.raises(ValueError, match="NaN"):
        solve_closed_form(w, bad)
    same = np.array([[10.0, 0.0, 0.0], [10.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match="coincide"):
        solve_closed_form(same, w)
    stacked = np.array([[10.0, 0.0, 0.0], [10.0, 0.0, 1.0]])  # on one vertical line
    with pytest.raises(ValueError, match="yaw is unobservable"):
        solve_closed_form(w, stacked)
    with pytest.raises(ValueError, match="shape"):
        solve_closed_form(w, w, np.eye(3))


def test_covariances_must_be_positive_semidefinite():
    w = np.array([[10.0, 0.0, 0.0], [12.0, 1.0, 0.0]])
    with pytest.raises(ValueError, match="cov_children_world is not positive semidefinite"):
        solve_closed_form(w, w, -np.eye(6))
    neg = iso_cov(2, 1e-3)
    neg[1, 2, 2] = -1e-6
    with pytest.raises(ValueError, match="cov_measurements is not positive semidefinite"):
        solve_closed_form(w, w, np.eye(6) * 1e-6, neg)
    # a semidefinite (singular) covariance is fine: one exactly known child
    cov = np.zeros((6, 6))
    cov[3:, 3:] = np.eye(3) * 1e-6
    assert solve_closed_form(w, w, cov).yaw_std > 0
