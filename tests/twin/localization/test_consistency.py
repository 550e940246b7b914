"""Wrong prisms and moved children are reported as typed errors, never as a wrong pose."""

import numpy as np
import pytest

from tests.twin.localization.helpers import iso_cov, measure_from
from twin.instruments.consistency import DEFAULT_FALSE_ALARM_RATE, chi2_threshold
from twin.instruments.errors import (
    ConsistencyError,
    FailureReason,
    InconsistentChildrenError,
    InconsistentMarkerError,
    InstrumentError,
)
from twin.instruments.marker import MarkerAssembly
from twin.instruments.shot import simulate_shot
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec
from twin.localization.closed_form import solve_closed_form
from twin.localization.observation import ChildObservation, observe_child
from twin.localization.sequence import CpsSequence
from twin.localization.wls import solve_wls

MARKER = MarkerAssembly()
SPEC = TotalStationSpec()
INCL = InclinometerSpec()
NEAR = MARKER.cubes_body + np.array([8.0, 0.25, -0.75])
FAR = MARKER.cubes_body + np.array([13.0, -0.25, -0.75])
STEP = np.array([5.0, 0.0, 0.0])


def observe(name, cubes, aims, rng, **kwargs):
    shots = [simulate_shot(cubes, a, SPEC, rng, inclinometer=INCL) for a in aims]
    meas = [s.measurement for s in shots]
    return [s.prism_index for s in shots], meas, observe_child(name, meas, SPEC, INCL, **kwargs)


def wrong_aims(cubes):
    """Aims at cube 1, 2 right, but at cube 0 with a prediction 60 % of the way to cube 1."""
    aims = cubes.copy()
    aims[0] = cubes[0] + 0.6 * (cubes[1] - cubes[0])
    return aims


def placed_sequence(rng, solver="wls", **kwargs):
    seq = CpsSequence(["a", "b"], solver=solver, **kwargs)
    seq.children_moved([observe("a", NEAR, NEAR, rng)[2], observe("b", FAR, FAR, rng)[2]])
    return seq


def test_wrong_prism_lock_is_detected_at_the_observation():
    rng = np.random.default_rng(0)
    far = FAR - STEP  # the far child seen from the parent's next station, 8 m away
    locked, meas, _ = observe("b", far, wrong_aims(far), rng, false_alarm_rate=None)
    assert locked == [1, 1, 2]  # the aim locked cube 1 for the shot at cube 0
    with pytest.raises(InconsistentMarkerError) as info:
        observe_child("b", meas, SPEC, INCL)
    err = info.value
    assert isinstance(err, ConsistencyError)
    assert isinstance(err, InstrumentError)
    assert err.reason is FailureReason.INCONSISTENT_MARKER
    assert err.details["dof"] == 3
    assert err.details["threshold"] == pytest.approx(chi2_threshold(3, 1e-4))
    assert err.details["chi2"] > 1e3 * err.details["threshold"]
    assert err.details["rms_residual"] > 0.05
    assert err.details["child"] == "b"
    # the same child shot right is accepted, and its marker fit is kept
    locked, _, obs = observe("b", far, far, rng)
    assert locked == [0, 1, 2]
    assert obs.marker_pose is not None
    assert obs.marker_pose.chi2 < chi2_threshold(3, DEFAULT_FALSE_ALARM_RATE)


def test_a_wrong_centroid_that_skipped_the_marker_test_is_caught_by_the_solver():
    # The centroid of (cube 1, cube 1, cube 2) is a few cm off with a mm covariance.
    for solver in ("wls", "closed_form"):
        rng = np.random.default_rng(0)
        seq = placed_sequence(rng, solver)
        before = (seq.state.copy(), seq.state_covariance.copy(), len(seq.steps))
        good_a = observe("a", NEAR - STEP, NEAR - STEP, rng)[2]
        far = FAR - STEP
        wrong_b = observe("b", far, wrong_aims(far), rng, false_alarm_rate=None)[2]
        with pytest.raises(InconsistentChildrenError) as info:
            seq.parent_moved([good_a, wrong_b])
        assert info.value.reason is FailureReason.INCONSISTENT_CHILDREN
        assert info.value.details["dof"] == 2
        assert info.value.details["chi2"] > 100 * info.value.details["threshold"]
        rejected = info.value.details["solution"]
        assert abs(rejected.pose.yaw) > 100 * rejected.yaw_std  # the pose it refused
        # nothing was recorded; measuring again (re-aiming) succeeds
        np.testing.assert_array_equal(seq.state, before[0])
        np.testing.assert_array_equal(seq.state_covariance, before[1])
        assert len(seq.steps) == before[2]
        step = seq.parent_moved([good_a, observe("b", far, far, rng)[2]])
        assert abs(step.parent.yaw) < 5 * step.parent.yaw_std
        np.testing.assert_allclose(step.parent.translation[:2], STEP[:2], atol=5e-3)


@pytest.mark.parametrize("solver", ["wls", "closed_form"])
def test_a_child_that_moved_between_the_measurements_is_detected(solver):
    rng = np.random.default_rng(3)
    seq = placed_sequence(rng, solver)
    # child b rolled 3 cm away from a (along the baseline) before the parent measured it
    baseline = (FAR - NEAR).mean(axis=0)
    moved = FAR + 0.03 * baseline / np.linalg.norm(baseline) - STEP
    obs = [observe("a", NEAR - STEP, NEAR - STEP, rng)[2], observe("b", moved, moved, rng)[2]]
    with pytest.raises(InconsistentChildrenError):
        seq.parent_moved(obs)
    # with the test off the pose is returned and its chi2 shows the move
    off = placed_sequence(np.random.default_rng(3), solver, false_alarm_rate=None)
    step = off.parent_moved(obs)
    assert step.solution.chi2 > 10 * chi2_threshold(2, DEFAULT_FALSE_ALARM_RATE)


def test_a_child_moved_across_the_baseline_needs_a_third_child():
    world = np.array([[8.0, 0.25, 0.65], [13.0, -0.25, 0.65], [10.0, 2.0, 0.65]])
    cov_w, cov_m = np.eye(9) * 1e-8, iso_cov(3, 1e-4)
    level = measure_from(0.0, STEP, world)
    d = world[1, :2] - world[0, :2]
    level[1, :2] += 0.03 * np.array([-d[1], d[0]]) / np.linalg.norm(d)  # 3 cm across
    with pytest.raises(InconsistentChildrenError, match="3 children"):
        solve_wls(world, level, cov_w, cov_m)
    # two children cannot tell this move from a yaw change (documented)
    sol = solve_closed_form(world[:2], level[:2], cov_w[:6, :6], cov_m[:2])
    assert sol.chi2 < 1.0


def test_closed_form_checks_its_unused_equations():
    world = np.array([[8.0, 0.0, 0.6], [13.0, 0.0, 0.7]])
    level = measure_from(0.1, STEP, world)
    bad = level.copy()
    bad[1, 0] += 10.0  # a 10 m baseline inconsistency
    with pytest.raises(InconsistentChildrenError, match="baseline length differs"):
        solve_closed_form(world, bad)  # no covariance: exact data
    height = level.copy()
    height[1, 2] += 0.05
    with pytest.raises(InconsistentChildrenError, match="height difference"):
        solve_closed_form(world, height, np.eye(6) * 1e-6, iso_cov(2, 1e-3))
    # consistent data give a chi2 that is reported
    sol = solve_closed_form(world, level, np.eye(6) * 1e-6, iso_cov(2, 1e-3))
    assert sol.chi2 == pytest.approx(0.0, abs=1e-12)
    assert sol.dof == 2


def test_closed_form_and_wls_chi2_agree_for_two_children():
    rng = np.random.default_rng(8)
    world = np.array([[8.0, 0.25, 0.6], [13.0, -0.25, 0.6]])
    cov_w = np.eye(6) * 1e-6
    cov_m = iso_cov(2, 2e-3)
    values = []
    for _ in range(200):
        level = measure_from(0.02, STEP, world) + 2e-3 * rng.standard_normal((2, 3))
        noisy_w = world + 1e-3 * rng.standard_normal((2, 3))
        cf = solve_closed_form(noisy_w, level, cov_w, cov_m, false_alarm_rate=None)
        wls = solve_wls(noisy_w, level, cov_w, cov_m, false_alarm_rate=None)
        assert cf.chi2 == pytest.approx(wls.chi2, rel=1e-3, abs=1e-6)
        values.append(wls.chi2)
    assert np.mean(values) == pytest.approx(2.0, abs=0.4)  # chi-square, 2 dof: SE 0.14


def test_false_alarm_rate_is_a_parameter():
    world = np.array([[8.0, 0.0, 0.6], [13.0, 0.0, 0.6]])
    level = measure_from(0.0, STEP, world)
    level[1, 0] += 3e-3  # 3 sigma on the baseline length
    cov_w, cov_m = np.zeros((6, 6)), iso_cov(2, 1e-3 / np.sqrt(2))
    for solve in (solve_closed_form, solve_wls):
        sol = solve(world, level, cov_w, cov_m)  # chi2 9 < 18.4 at 1e-4
        assert sol.chi2 == pytest.approx(9.0, rel=1e-3)
        with pytest.raises(InconsistentChildrenError):
            solve(world, level, cov_w, cov_m, false_alarm_rate=0.05)  # 6.0
        with pytest.raises(ValueError, match="false_alarm_rate"):
            solve(world, level, cov_w, cov_m, false_alarm_rate=1.5)
    with pytest.raises(ValueError, match="false_alarm_rate"):
        CpsSequence(["a", "b"], false_alarm_rate=0.0)


def test_levelled_shots_need_the_inclinometer_for_their_covariance():
    rng = np.random.default_rng(1)
    _, meas, _ = observe("a", NEAR, NEAR, rng)
    with pytest.raises(ValueError, match="inclinometer"):
        observe_child("a", meas, SPEC)
    with_tilt = observe_child("a", meas, SPEC, INCL)
    exact_tilt = observe_child("a", meas, SPEC, InclinometerSpec(sigma=0.0))
    assert np.trace(with_tilt.covariance) > np.trace(exact_tilt.covariance)


def test_observation_rejects_a_covariance_that_is_not_psd():
    with pytest.raises(ValueError, match=r"observation of 'a'.*positive semidefinite"):
        ChildObservation("a", np.zeros(3), -np.eye(3))
