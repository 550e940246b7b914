"""The CPS sequence: exact recovery, the step record, joint covariance propagation."""

import numpy as np
import pytest

from tests.twin.localization.helpers import measure_from
from twin.localization.observation import ChildObservation
from twin.localization.pose import ParentPose
from twin.localization.sequence import CpsSequence, StepKind

COV = np.eye(3) * 1e-6


def leapfrog_truth(n_steps, n_children=2):
    """Parent stations (yaw, t) and children positions for a wavy straight run."""
    stations = [(0.0, np.zeros(3))]
    children = []
    for k in range(n_steps):
        x = 5.0 * (k + 1)
        spots = [[x + 3.0 + 4.0 * i, (-1) ** i * 0.4, 0.6 + 0.1 * i] for i in range(n_children)]
        children.append(np.array(spots))
        stations.append((0.02 * np.sin(k), np.array([x, 0.1 * np.cos(k), 0.01 * k])))
    return stations, children


def run_sequence(stations, children, solver, noise=None):
    """Run a sequence; ``noise`` is (steps, 2, n_children, 3) added to the measurements."""
    names = [f"c{i}" for i in range(children[0].shape[0])]
    seq = CpsSequence(names, solver=solver)
    for k, spots in enumerate(children):
        for phase, station in enumerate((stations[k], stations[k + 1])):
            level = measure_from(*station, spots)
            if noise is not None:
                level = level + noise[k, phase]
            obs = [
                ChildObservation(n, level[i], COV, timestamp=2.0 * k + phase)
                for i, n in enumerate(names)
            ]
            (seq.children_moved if phase == 0 else seq.parent_moved)(obs)
    return seq


@pytest.mark.parametrize(("solver", "n_children"), [("closed_form", 2), ("wls", 2), ("wls", 3)])
def test_noise_free_sequence_recovers_every_station(solver, n_children):
    stations, children = leapfrog_truth(6, n_children)
    seq = run_sequence(stations, children, solver)
    parent_steps = [s for s in seq.steps if s.kind is StepKind.PARENT_MOVED]
    assert len(parent_steps) == 6
    for step, (yaw, t) in zip(parent_steps, stations[1:], strict=True):
        assert step.parent.yaw == pytest.approx(yaw, abs=1e-12)
        np.testing.assert_allclose(step.parent.translation, t, atol=1e-10)
    for step, spots in zip(seq.steps[::2], children, strict=True):
        np.testing.assert_allclose(step.children_world, spots, atol=1e-10)


def test_the_record_says_who_moved_and_what_was_measured():
    stations, children = leapfrog_truth(2)
    seq = run_sequence(stations, children, "wls")
    steps = seq.steps
    assert [s.index for s in steps] == [0, 1, 2, 3]
    assert [s.kind for s in steps] == [StepKind.CHILDREN_MOVED, StepKind.PARENT_MOVED] * 2
    assert steps[0].moved == ("c0", "c1")
    assert steps[1].moved == ("parent",)
    assert steps[0].solution is None
    assert steps[1].solution.method == "wls"
    assert [o.child for o in steps[1].observations] == ["c0", "c1"]
    assert [s.timestamp for s in steps] == [0.0, 1.0, 2.0, 3.0]
    assert steps[1].state_covariance.shape == (10, 10)
    # the record is a read-only snapshot
    with pytest.raises(ValueError, match="read-only"):
        steps[0].children_world[0, 0] = 1e9


def test_children_not_yet_placed_are_nan():
    seq = CpsSequence(["a", "b", "c"])
    step = seq.children_moved([ChildObservation("a", [5.0, 0.0, 0.0], COV)])
    assert np.all(np.isfinite(step.children_world[0]))
    assert np.all(np.isnan(step.children_world[1:]))
    assert np.all(np.isfinite(step.state_covariance))
    with pytest.raises(ValueError, match="has not been measured"):
        seq.child_position("b")


def test_children_inherit_the_parents_covariance_and_become_correlated():
    p0 = np.diag([1e-6, 4e-6, 9e-6, 1e-6])
    seq = CpsSequence(["a", "b"], ParentPose(0.0, np.zeros(3), p0))
    ma, mb = np.array([5.0, 1.0, 0.5]), np.array([9.0, -1.0, 0.5])
    seq.children_moved([ChildObservation("a", ma, COV), ChildObservation("b", mb, COV)])
    p = seq.state_covariance

    def jac(m):  # d(R m + t)/d(yaw, t) at yaw = 0
        return np.column_stack([[-m[1], m[0], 0.0], np.eye(3)])

    np.testing.assert_allclose(p[4:7, 4:7], jac(ma) @ p0 @ jac(ma).T + COV, atol=1e-18)
    np.testing.assert_allclose(p[4:7, 7:10], jac(ma) @ p0 @ jac(mb).T, atol=1e-18)
    np.testing.assert_allclose(p[:4, 4:7], p0 @ jac(ma).T, atol=1e-18)
    pos, cov = seq.child_position("b")
    np.testing.assert_allclose(pos, mb)
    np.testing.assert_allclose(cov, p[7:10, 7:10])


@pytest.mark.parametrize("solver", ["closed_form", "wls"])
def test_propagated_covariance_equals_the_linearised_chain(solver):
    # Differentiate the whole estimator chain numerically with respect to every
    # measurement: J Cov J^T must equal the sequence's propagated covariance.
    stations, children = leapfrog_truth(4)
    shape = (4, 2, 2, 3)
    final = run_sequence(stations, children, solver).parent
    n = int(np.prod(shape))
    jac = np.empty((4, n))
    h = 1e-6
    for k in range(n):
        e = np.zeros(n)
        e[k] = h
        plus = run_sequence(stations, children, solver, e.reshape(shape)).parent.vector
        minus = run_sequence(stations, children, solver, -e.reshape(shape)).parent.vector
        jac[:, k] = (plus - minus) / (2 * h)
    expected = jac @ (np.eye(n) * COV[0, 0]) @ jac.T
    np.testing.assert_allclose(final.covariance, expected, rtol=1e-4, atol=1e-14)


def test_uncertainty_grows_with_distance():
    stations, children = leapfrog_truth(8)
    seq = run_sequence(stations, children, "wls")
    traces = [np.trace(s.parent.position_covariance) for s in seq.steps[1::2]]
    assert np.all(np.diff(traces) > 0)
    assert traces[-1] > 4 * traces[0]


def test_bad_input():
    with pytest.raises(ValueError, match="at least two children"):
        CpsSequence(["only"])
    with pytest.raises(ValueError, match="unique"):
        CpsSequence(["a", "a"])
    with pytest.raises(ValueError, match="solver"):
        CpsSequence(["a", "b"], solver="magic")
    seq = CpsSequence(["a", "b"])
    obs_a = ChildObservation("a", [5.0, 0.0, 0.0], COV)
    obs_b = ChildObservation("b", [9.0, 1.0, 0.0], COV)
    with pytest.raises(ValueError, match="never placed"):
        seq.parent_moved([obs_a, obs_b])
    with pytest.raises(ValueError, match="unknown child 'z'"):
        seq.children_moved([ChildObservation("z", [1.0, 2.0, 3.0], COV)])
    with pytest.raises(ValueError, match="observed twice"):
        seq.children_moved([obs_a, obs_a])
    seq.children_moved([obs_a, obs_b])
    with pytest.raises(ValueError, match="at least 2"):
        seq.parent_moved([obs_a])
    with pytest.raises(ValueError, match="NaN"):
        ChildObservation("a", [np.nan, 0.0, 0.0], COV)
    with pytest.raises(ValueError, match="covariance"):
        ChildObservation("a", [1.0, 0.0, 0.0], np.eye(2))
    assert len(seq.steps) == 1  # failed steps leave no record


def test_the_parent_pose_follows_every_step():
    stations, children = leapfrog_truth(3)
    names = ["c0", "c1"]
    seq = CpsSequence(names, solver="wls")
    assert seq.parent.yaw == 0.0
    for k, spots in enumerate(children):
        for phase, station in enumerate((stations[k], stations[k + 1])):
            level = measure_from(*station, spots)
            obs = [
                ChildObservation(n, level[i], COV, timestamp=2.0 * k + phase)
                for i, n in enumerate(names)
            ]
            step = (seq.children_moved if phase == 0 else seq.parent_moved)(obs)
            # The same as a pose built afresh from the state, at every step.
            fresh = ParentPose(
                seq.state[0], seq.state[1:4], seq.state_covariance[:4, :4], step.timestamp
            )
            pose = seq.parent
            assert pose.yaw == fresh.yaw
            assert pose.timestamp == fresh.timestamp
            np.testing.assert_array_equal(pose.translation, fresh.translation)
            np.testing.assert_array_equal(pose.covariance, fresh.covariance)
            np.testing.assert_array_equal(step.parent.translation, pose.translation)
        assert seq.parent.yaw == pytest.approx(stations[k + 1][0], abs=1e-12)
