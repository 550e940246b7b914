"""The CPS solvers over T trials: each trial is the one-trial solver's solution, near the
truth; the flags are where the one-trial solver raises."""

import warnings

import numpy as np
import pytest

from calib.rotation import rot_z
from twin.instruments.errors import InconsistentChildrenError
from twin.localization.closed_form import solve_closed_form, solve_closed_form_batch
from twin.localization.input_checks import ConvergenceWarning, PoorGeometryWarning
from twin.localization.wls import solve_wls, solve_wls_batch

T = 30


def problem(n_trials, n_children, seed, sigma=2e-3, truth=False):
    """Random parent poses and children with correlated world covariances (as a sequence
    gives them) and noisy measurements; some trials' children are close together. With
    ``truth``, also the true (T,) yaws and (T, 3) translations."""
    rng = np.random.default_rng(seed)
    yaw = rng.uniform(-np.pi, np.pi, n_trials)
    t = rng.uniform(-20, 20, (n_trials, 3))
    spread = rng.choice([0.05, 5.0], size=(n_trials, 1, 1), p=[0.2, 0.8])
    world = rng.uniform(-1, 1, (n_trials, n_children, 3)) * spread + t[:, None] + [4.0, 0, 0]
    root = rng.standard_normal((n_trials, 3 * n_children, 3 * n_children)) * sigma
    cov_world = root @ np.swapaxes(root, -1, -2) / (3 * n_children)
    cov_m = np.tile(np.eye(3) * sigma**2, (n_trials, n_children, 1, 1))
    level = (world - t[:, None]) @ rot_z(yaw)
    level = level + sigma * rng.standard_normal(level.shape)
    if truth:
        return world, level, cov_world, cov_m, yaw, t
    return world, level, cov_world, cov_m


def scalar(solve, world, level, cov_world, cov_m, i):
    """The one-trial solution of trial i and whether it warned of poor geometry."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        solution = solve(world[i], level[i], cov_world[i], cov_m[i], false_alarm_rate=None)
    return solution, any(issubclass(w.category, PoorGeometryWarning) for w in caught)


def close(actual, expected, rtol=1e-10):
    np.testing.assert_allclose(actual, expected, rtol=0, atol=rtol * np.max(np.abs(expected)))


@pytest.mark.parametrize(
    ("solve", "solve_batch", "n_children"),
    [
        (solve_closed_form, solve_closed_form_batch, 2),
        (solve_wls, solve_wls_batch, 2),
        (solve_wls, solve_wls_batch, 4),
    ],
)
def test_each_trial_is_the_one_trial_solution_near_the_truth(solve, solve_batch, n_children):
    world, level, cov_world, cov_m, yaw, t = problem(T, n_children, n_children, truth=True)
    batch = solve_batch(world, level, cov_world, cov_m, timestamp=2.0)
    assert batch.pose.timestamp == 2.0
    assert batch.dof == (2 if solve is solve_closed_form else 3 * n_children - 4)
    for i in range(T):
        solution, poor = scalar(solve, world, level, cov_world, cov_m, i)
        assert batch.pose.yaw[i] == pytest.approx(solution.pose.yaw, abs=1e-12)
        close(batch.pose.translation[i], solution.pose.translation)
        close(batch.pose.covariance[i], solution.pose.covariance)
        close(batch.children_jacobian[i], solution.children_jacobian)
        close(batch.measurement_jacobian[i], solution.measurement_jacobian)
        assert batch.chi2[i] == pytest.approx(solution.chi2, rel=1e-10)
        assert batch.baseline[i] == pytest.approx(solution.baseline, rel=1e-14)
        assert batch.iterations[i] == solution.iterations
        assert batch.poor_yaw[i] == poor
    assert batch.poor_yaw.any()  # the close children
    # The truth within 5 predicted sigma (the world positions are exact here, so the
    # predicted covariance, which counts their noise, is the larger).
    error = np.column_stack([np.sin(batch.pose.yaw - yaw), batch.pose.translation - t])
    sigma = np.sqrt(np.diagonal(batch.pose.covariance, axis1=1, axis2=2))
    assert np.all(np.abs(error) < 5 * sigma)


@pytest.mark.parametrize("solve_batch", [solve_closed_form_batch, solve_wls_batch])
def test_the_flags_are_where_the_scalar_solver_raises(solve_batch):
    world, level, cov_world, cov_m = problem(6, 2, 7)
    level[1, 0] += [0.0, 0.0, 0.05]  # trial 1: a child 5 cm higher than it was
    level[4, 1] = level[4, 0] + [0.0, 0.0, 0.3]  # trial 4: children on one vertical
    world[4, 1] = world[4, 0] + [0.0, 0.0, 0.3]
    batch = solve_batch(world, level, cov_world, cov_m)
    assert batch.inconsistent.tolist() == [False, True, False, False, False, False]
    assert batch.poor_geometry.tolist() == [False, False, False, False, True, False]
    assert batch.failed.tolist() == [False, True, False, False, True, False]
    assert np.all(np.isnan(batch.pose.vector[4]))
    assert np.all(np.isfinite(np.delete(batch.pose.covariance, 4, axis=0)))
    solve = solve_wls if solve_batch is solve_wls_batch else solve_closed_form
    with pytest.raises(InconsistentChildrenError):
        solve(world[1], level[1], cov_world[1], cov_m[1])
    with pytest.raises(ValueError, match="coincide"):
        solve(world[4], level[4], cov_world[4], cov_m[4])
    assert batch.trial(1).chi2 == batch.chi2[1]  # the inconsistent solution is kept
    off = solve_batch(world, level, cov_world, cov_m, false_alarm_rate=None)
    assert not off.inconsistent.any()
    np.testing.assert_array_equal(off.chi2, batch.chi2)


def test_wls_warns_once_for_trials_that_do_not_converge():
    world, level, cov_world, cov_m = problem(5, 3, 8)
    with pytest.warns(ConvergenceWarning, match="in 5 of 5 trials"):
        batch = solve_wls_batch(world, level, cov_world, cov_m, max_iterations=1)
    assert not batch.converged.any()
    assert np.all(batch.iterations == 1)


def test_noise_free_closed_form_without_covariances_is_exact():
    rng = np.random.default_rng(9)
    yaw, t = rng.uniform(-np.pi, np.pi, 8), rng.uniform(-20, 20, (8, 3))
    world = rng.uniform(-5, 5, (8, 2, 3))
    level = (world - t[:, None]) @ rot_z(yaw)
    batch = solve_closed_form_batch(world, level)
    np.testing.assert_allclose(np.sin(batch.pose.yaw - yaw), 0.0, atol=1e-12)
    np.testing.assert_allclose(batch.pose.translation, t, atol=1e-12)
    assert np.all(batch.chi2 < 1e-6)  # mismatch below 1e-12 m against the 1e-9 m floor
    assert np.all(batch.pose.covariance == 0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"world": np.zeros((3, 1, 3))}, "N >= 2"),
        ({"level": np.zeros((3, 3, 3))}, "shape"),
        ({"cov_world": np.zeros((3, 5, 5))}, "cov_children_world must have shape"),
        ({"cov_m": np.zeros((3, 2, 3))}, "cov_measurements must have shape"),
        ({"cov_m": -np.ones((3, 2, 3, 3))}, "positive semidefinite"),
    ],
)
def test_bad_input(kwargs, match):
    world, level, cov_world, cov_m = problem(3, 2, 10)
    args = {"world": world, "level": level, "cov_world": cov_world, "cov_m": cov_m} | kwargs
    with pytest.raises(ValueError, match=match):
        solve_wls_batch(args["world"], args["level"], args["cov_world"], args["cov_m"])
    with pytest.raises(ValueError, match="exactly two"):
        solve_closed_form_batch(*problem(3, 3, 11))
