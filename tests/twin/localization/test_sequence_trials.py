"""The CPS sequence over trials: each trial equals :class:`CpsSequence` on its data."""

import numpy as np
import pytest

from calib.rotation import rot_z
from twin.instruments.consistency import DEFAULT_FALSE_ALARM_RATE, chi2_threshold
from twin.localization.joint_state import CpsBatch
from twin.localization.leapfrog import CHILDREN, STEP_DURATION, LeapfrogConfig, simulate_leapfrog
from twin.localization.observation import ChildObservation, ChildObservationBatch
from twin.localization.pose import ParentPose, ParentPoseBatch
from twin.localization.sequence import CpsSequence

SOLVERS = ("closed_form", "wls")
N_TRIALS = 40
CONFIG = LeapfrogConfig(route_length=50.0)  # 10 legs of 5 m
COV = np.eye(3) * 1e-6


@pytest.fixture(scope="module")
def data():
    return simulate_leapfrog(CONFIG, N_TRIALS, np.random.default_rng(21))


def leg_observations(data, k, trials):
    """The batched observations of leg k: (before, after) for ``trials``."""
    out = []
    for phase, (points, cov) in enumerate(
        ((data.before, data.before_cov), (data.after, data.after_cov))
    ):
        stamp = (2 * k + phase) * STEP_DURATION
        out.append(
            [
                ChildObservationBatch(name, points[trials, k, i], cov[trials, k, i], stamp)
                for i, name in enumerate(CHILDREN)
            ]
        )
    return out


def run_batch(data, solver, trials):
    """Run the batch over every leg; returns it and the parent steps' solutions."""
    batch = CpsBatch(CHILDREN, len(trials), solver=solver)
    solutions = []
    for k in range(CONFIG.n_steps):
        before, after = leg_observations(data, k, trials)
        batch.children_moved(before)
        solutions.append(batch.parent_moved(after))
    return batch, solutions


def close(actual, expected, rtol=1e-10):
    """Equal to ``rtol`` relative to the largest entry of ``expected``."""
    np.testing.assert_allclose(actual, expected, rtol=0, atol=rtol * np.max(np.abs(expected)))


@pytest.mark.parametrize("solver", SOLVERS)
def test_each_trial_equals_the_scalar_sequence_at_every_step(data, solver):
    trials = np.arange(N_TRIALS)
    batch = CpsBatch(CHILDREN, N_TRIALS, solver=solver)
    # The scalar sequences test nothing: a step the test fails must not stop them.
    seqs = [CpsSequence(CHILDREN, solver=solver, false_alarm_rate=None) for _ in trials]
    threshold = chi2_threshold(2, DEFAULT_FALSE_ALARM_RATE)
    for k in range(CONFIG.n_steps):
        for phase, obs in enumerate(leg_observations(data, k, trials)):
            if phase == 0:
                batch.children_moved(obs)
            else:
                solution = batch.parent_moved(obs)
            for i, seq in enumerate(seqs):
                step = (seq.children_moved, seq.parent_moved)[phase]([o.trial(i) for o in obs])
                close(batch.state[i], seq.state)
                close(batch.state_covariance[i], seq.state_covariance)
                if phase == 1:
                    assert solution.chi2[i] == pytest.approx(step.solution.chi2, rel=1e-10)
                    assert solution.inconsistent[i] == (step.solution.chi2 > threshold)
                    assert solution.iterations[i] == step.solution.iterations
                    close(solution.children_jacobian[i], step.solution.children_jacobian)
                    close(solution.measurement_jacobian[i], step.solution.measurement_jacobian)
                    assert solution.baseline[i] == pytest.approx(step.solution.baseline)
    assert batch.timestamp == seqs[0].parent.timestamp
    assert batch.n_steps == len(seqs[0].steps)
    assert not batch.lost.any()
    for i, seq in enumerate(seqs):
        parent = batch.parent.trial(i)
        assert parent.yaw == pytest.approx(seq.parent.yaw, abs=1e-12)
        close(parent.covariance, seq.parent.covariance)
        position, cov = batch.child_position("child2")
        close(position[i], seq.child_position("child2")[0])
        close(cov[i], seq.child_position("child2")[1])


@pytest.mark.parametrize("solver", SOLVERS)
def test_a_trial_does_not_depend_on_its_batch(data, solver):
    full, full_solutions = run_batch(data, solver, np.arange(N_TRIALS))
    backwards, _ = run_batch(data, solver, np.arange(N_TRIALS)[::-1])
    np.testing.assert_array_equal(backwards.state[::-1], full.state)
    np.testing.assert_array_equal(backwards.state_covariance[::-1], full.state_covariance)
    for i in (0, 13, N_TRIALS - 1):
        one, solutions = run_batch(data, solver, np.array([i]))
        np.testing.assert_array_equal(one.state[0], full.state[i])
        np.testing.assert_array_equal(one.state_covariance[0], full.state_covariance[i])
        for a, b in zip(solutions, full_solutions, strict=True):
            assert a.chi2[0] == b.chi2[i]


def observe(names, spots, yaw, t, cov):
    """Exact observations (T trials) of children at (T, N, 3) world ``spots`` from a parent
    at (yaw (T,), t (T, 3))."""
    level = (spots - t[:, None]) @ rot_z(yaw)
    return [ChildObservationBatch(n, level[:, j], cov) for j, n in enumerate(names)]


def noise_free_run(solver, n_children, n_trials, n_legs, seed):
    """Random stations and children per trial; exact measurements of every leg."""
    rng = np.random.default_rng(seed)
    names = [f"c{i}" for i in range(n_children)]
    start = ParentPoseBatch(
        rng.uniform(-np.pi, np.pi, n_trials),
        rng.uniform(-50, 50, (n_trials, 3)),
        np.tile(np.diag([1e-6, 1e-4, 1e-4, 1e-4]), (n_trials, 1, 1)),
    )
    batch = CpsBatch(names, n_trials, start, solver=solver)
    yaw, t = start.yaw.copy(), start.translation.copy()
    cov = np.tile(COV, (n_trials, 1, 1))
    for _ in range(n_legs):
        # children 3-10 m ahead of the parent and spread across, anywhere in height
        shape = (n_trials, n_children)
        ahead = np.stack(
            [rng.uniform(3, 10, shape), rng.uniform(-4, 4, shape), rng.uniform(-1, 1, shape)], -1
        )
        spots = ahead @ np.swapaxes(rot_z(yaw), -1, -2) + t[:, None]
        batch.children_moved(observe(names, spots, yaw, t, cov))
        yaw = yaw + rng.uniform(-0.5, 0.5, n_trials)
        t = t + rng.uniform(-5, 5, (n_trials, 3))
        solution = batch.parent_moved(observe(names, spots, yaw, t, cov))
        assert not solution.failed.any()
        np.testing.assert_allclose(np.sin(batch.parent.yaw - yaw), 0.0, atol=1e-12)
        np.testing.assert_allclose(np.cos(batch.parent.yaw - yaw), 1.0)
        np.testing.assert_allclose(batch.parent.translation, t, atol=1e-10)
        np.testing.assert_allclose(batch.children_world, spots, atol=1e-10)
        np.testing.assert_allclose(solution.chi2, 0.0, atol=1e-12)


@pytest.mark.parametrize(("solver", "n_children"), [("closed_form", 2), ("wls", 2), ("wls", 3)])
def test_noise_free_data_give_the_exact_poses(solver, n_children):
    noise_free_run(solver, n_children, n_trials=16, n_legs=5, seed=n_children)


@pytest.mark.parametrize("solver", SOLVERS)
def test_a_child_that_moved_is_flagged_in_its_trial_only(data, solver):
    trials = np.arange(N_TRIALS)
    batch = CpsBatch(CHILDREN, N_TRIALS, solver=solver, false_alarm_rate=1e-6)
    before, after = leg_observations(data, 0, trials)
    batch.children_moved(before)
    moved = after[1].point_level.copy()
    moved[5] += [0.05, 0.0, 0.0]  # trial 5: child 2 moved 5 cm along the baseline
    after[1] = ChildObservationBatch("child2", moved, after[1].covariance)
    solution = batch.parent_moved(after)
    assert solution.inconsistent[5]
    assert np.count_nonzero(solution.inconsistent) == 1
    # the solution is kept: the parent moved (by about the step length) in every trial
    assert np.all(batch.parent.translation[:, 0] > 4.0)


@pytest.mark.parametrize("solver", SOLVERS)
def test_poor_geometry_loses_its_trial_and_no_other(data, solver):
    trials = np.arange(8)
    batch = CpsBatch(CHILDREN, 8, solver=solver)
    before, after = leg_observations(data, 0, trials)
    together = before[1].point_level.copy()
    together[3] = before[0].point_level[3] + [0.0, 0.0, 0.1]  # trial 3: on one vertical
    before[1] = ChildObservationBatch("child2", together, before[1].covariance)
    batch.children_moved(before)
    solution = batch.parent_moved(after)
    assert solution.poor_geometry.tolist() == [i == 3 for i in range(8)]
    assert not solution.inconsistent[3]
    assert solution.failed[3]
    assert solution.baseline[3] < 1e-3
    assert batch.lost.tolist() == [i == 3 for i in range(8)]
    assert np.all(np.isnan(batch.state[3]))
    assert np.all(np.isfinite(np.delete(batch.state_covariance, 3, axis=0)))
    with pytest.raises(ValueError, match="no solution"):
        solution.trial(3)
    # the lost trial stays lost; the others go on
    before, after = leg_observations(data, 1, trials)
    batch.children_moved(before)
    solution = batch.parent_moved(after)
    assert solution.poor_geometry.tolist() == [i == 3 for i in range(8)]
    assert np.all(np.isfinite(np.delete(batch.state, 3, axis=0)))


def test_a_per_trial_initial_pose_is_each_trials_start():
    pose = ParentPose(0.3, np.array([1.0, 2.0, 0.5]), np.diag([1e-6, 1e-4, 1e-4, 1e-4]))
    same = CpsBatch(CHILDREN, 3, pose)
    np.testing.assert_array_equal(same.parent.vector, np.tile(pose.vector, (3, 1)))
    per_trial = ParentPoseBatch.repeat(pose, 3)
    batch = CpsBatch(CHILDREN, 3, per_trial)
    np.testing.assert_array_equal(batch.state_covariance[:, :4, :4], per_trial.covariance)
    assert np.all(np.isnan(batch.children_world))
    with pytest.raises(ValueError, match="initial_pose has 3 trials"):
        CpsBatch(CHILDREN, 4, per_trial)


def test_the_parent_maps_points_to_the_world():
    pose = ParentPoseBatch(
        [0.0, np.pi / 2], [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], np.zeros((2, 4, 4))
    )
    np.testing.assert_allclose(
        pose.level2world([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]),
        [[2.0, 0.0, 0.0], [0.0, 1.0, 1.0]],
        atol=1e-15,
    )
    assert pose.level2world(np.zeros((2, 5, 3))).shape == (2, 5, 3)


def test_bad_input():
    obs = [
        ChildObservationBatch("a", [[5.0, 0.0, 0.0]] * 2, [COV] * 2),
        ChildObservationBatch("b", [[9.0, 1.0, 0.0]] * 2, [COV] * 2),
    ]
    with pytest.raises(ValueError, match="at least two children"):
        CpsBatch(["only"], 2)
    with pytest.raises(ValueError, match="unique"):
        CpsBatch(["a", "a"], 2)
    with pytest.raises(ValueError, match="solver"):
        CpsBatch(["a", "b"], 2, solver="magic")
    with pytest.raises(ValueError, match="n_trials"):
        CpsBatch(["a", "b"], 0)
    batch = CpsBatch(["a", "b", "c"], 2, solver="closed_form")
    with pytest.raises(ValueError, match="never placed"):
        batch.parent_moved(obs)
    with pytest.raises(ValueError, match="has 2 trials, the batch 3"):
        CpsBatch(["a", "b"], 3).children_moved(obs)
    with pytest.raises(ValueError, match="unknown child 'z'"):
        batch.children_moved([ChildObservationBatch("z", [[1.0, 2.0, 3.0]] * 2, [COV] * 2)])
    with pytest.raises(ValueError, match="observed twice"):
        batch.children_moved([obs[0], obs[0]])
    with pytest.raises(ValueError, match="has not been measured"):
        batch.child_position("a")
    batch.children_moved(obs)
    with pytest.raises(ValueError, match="at least 2"):
        batch.parent_moved(obs[:1])
    c = ChildObservationBatch("c", [[7.0, -1.0, 0.0]] * 2, [COV] * 2)
    batch.children_moved([c])
    with pytest.raises(ValueError, match="exactly two children"):
        batch.parent_moved([*obs, c])
    assert batch.n_steps == 2
    zero = CpsBatch(["a", "b"], 2)
    exact = [ChildObservationBatch(o.child, o.point_level, np.zeros((2, 3, 3))) for o in obs]
    zero.children_moved(exact)
    with pytest.raises(ValueError, match="not positive definite"):
        zero.parent_moved(exact)


def test_scalar_observations_of_one_trial_round_trip():
    obs = ChildObservationBatch("a", [[5.0, 0.0, 0.0], [6.0, 1.0, 0.0]], [COV, 2 * COV], 3.0)
    one = obs.trial(1)
    assert isinstance(one, ChildObservation)
    np.testing.assert_array_equal(one.covariance, 2 * COV)
    assert one.timestamp == 3.0
