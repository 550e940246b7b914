"""Monte Carlo of the straight 85 m leapfrog: consistency (NEES) and formation geometry."""

import numpy as np
import pytest
from scipy.stats import chi2, norm, poisson

from twin.instruments.consistency import DEFAULT_FALSE_ALARM_RATE
from twin.instruments.errors import ConsistencyError, FailureReason
from twin.instruments.total_station import ARCSEC
from twin.localization.leapfrog import (
    Formation,
    LeapfrogConfig,
    evaluate,
    run_cps,
    simulate_leapfrog,
)
from twin.localization.sequence import StepKind

N_RUNS = 500
SOLVERS = ("closed_form", "wls")
K = 4.4
"""Standard errors of a band: two-sided, a false alarm once in 100 000 for each check."""
TAIL = norm.sf(K)


@pytest.fixture(scope="module")
def datasets():
    return {
        formation: simulate_leapfrog(
            LeapfrogConfig(formation=formation), N_RUNS, np.random.default_rng(100 + seed)
        )
        for seed, formation in enumerate(Formation)
    }


@pytest.fixture(scope="module")
def results(datasets):
    return {
        formation: {solver: evaluate(data, solver) for solver in SOLVERS}
        for formation, data in datasets.items()
    }


@pytest.mark.slow
@pytest.mark.parametrize("formation", list(Formation))
@pytest.mark.parametrize("solver", SOLVERS)
def test_clean_runs_raise_consistency_errors_at_the_false_alarm_rate(results, formation, solver):
    # Clean data: every rejected run is a false alarm. Tests per run: 17 steps x (4 marker
    # fits + 1 parent solve); a run stops at its first alarm, so rejected runs <= alarms.
    res = results[formation][solver]
    expected = N_RUNS * 17 * 5 * DEFAULT_FALSE_ALARM_RATE  # 4.25
    assert len(res.rejected_runs) <= poisson.isf(1e-3, expected)  # 12
    assert len(res.position_error) == N_RUNS - len(res.rejected_runs)


@pytest.mark.slow
def test_marker_chi2_follows_its_law_on_clean_data(datasets):
    for data in datasets.values():
        values = np.concatenate([data.before_marker_chi2.ravel(), data.after_marker_chi2.ravel()])
        assert values.size == 34_000
        # chi-square, 3 dof: mean 3 (standard error sqrt(6 / n) = 0.013), 1 % tail (standard
        # error 0.054 %), each held to K standard errors.
        n = values.size
        assert values.mean() == pytest.approx(3.0, abs=K * np.sqrt(6 / n))
        tail = np.mean(values > chi2.isf(0.01, 3))
        assert tail == pytest.approx(0.01, abs=K * np.sqrt(0.01 * 0.99 / n))


@pytest.mark.slow
@pytest.mark.parametrize("solver", SOLVERS)
def test_parent_step_chi2_follows_its_law_on_clean_data(datasets, solver):
    data = datasets[Formation.IN_LINE]
    values = np.array(
        [
            step.solution.chi2
            for run in range(60)
            for step in run_cps(data, run, solver, false_alarm_rate=None).steps
            if step.solution is not None
        ]
    )
    assert values.size == 60 * 17
    assert values.mean() == pytest.approx(2.0, abs=0.3)  # chi-square, 2 dof: SE 0.063


@pytest.mark.slow
@pytest.mark.parametrize("formation", list(Formation))
@pytest.mark.parametrize("solver", SOLVERS)
def test_predicted_covariance_is_consistent(results, formation, solver):
    res = results[formation][solver]
    # n runs' NEES sum to chi-square with 3n (position) and n (yaw) degrees of freedom: held
    # to its quantiles at K standard errors' worth of tail ([2.54, 3.51] and [0.75, 1.30] for
    # n = 500; the yaw band was 3 standard errors, failing once in 100 runs of the four).
    n = len(res.position_nees)
    for nees, dof in ((res.position_nees, 3), (res.yaw_nees, 1)):
        low, high = chi2.ppf(TAIL, dof * n) / n, chi2.isf(TAIL, dof * n) / n
        assert low <= nees.mean() <= high, (dof, nees.mean(), low, high)


@pytest.mark.slow
@pytest.mark.parametrize("solver", SOLVERS)
def test_side_by_side_is_clearly_worse_and_the_prediction_says_so(results, solver):
    line = results[Formation.IN_LINE][solver]
    side = results[Formation.SIDE_BY_SIDE][solver]
    actual = np.median(side.position_error_norm) / np.median(line.position_error_norm)
    predicted = np.median(side.predicted_position_rms) / np.median(line.predicted_position_rms)
    yaw_actual = np.median(np.abs(side.yaw_error)) / np.median(np.abs(line.yaw_error))
    # the formations are independent runs (false alarms leave different runs out): compare
    # medians, not run by run
    yaw_predicted = np.sqrt(
        np.median(side.covariance[:, 0, 0]) / np.median(line.covariance[:, 0, 0])
    )
    assert actual > 3.0
    assert predicted > 3.0
    assert yaw_actual > 3.0
    assert yaw_predicted > 3.0
    assert predicted == pytest.approx(actual, rel=0.3)


@pytest.mark.slow
def test_wls_is_no_worse_than_the_closed_form(results):
    for formation in Formation:
        cf, wls = results[formation]["closed_form"], results[formation]["wls"]
        assert np.median(wls.predicted_position_rms) <= np.median(cf.predicted_position_rms)
        assert np.mean(wls.position_error_norm**2) < 1.1 * np.mean(cf.position_error_norm**2)


def test_simulation_is_reproducible_bit_for_bit():
    cfg = LeapfrogConfig(route_length=20.0)
    a = simulate_leapfrog(cfg, 3, np.random.default_rng(5))
    b = simulate_leapfrog(cfg, 3, np.random.default_rng(5))
    c = simulate_leapfrog(cfg, 3, np.random.default_rng(6))
    for name in ("parent_truth", "children_truth", "before", "after", "before_cov", "after_cov"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert not np.array_equal(a.after, c.after)
    ra, rb = evaluate(a, "wls"), evaluate(b, "wls")
    np.testing.assert_array_equal(ra.position_error, rb.position_error)


@pytest.mark.parametrize("solver", SOLVERS)
def test_all_runs_at_once_stop_and_end_as_each_run_alone(solver):
    # At a false-alarm rate of 2 % about half the runs stop, on a marker or on the children.
    data = simulate_leapfrog(LeapfrogConfig(), 24, np.random.default_rng(11))
    res = evaluate(data, solver, false_alarm_rate=0.02)
    kept, reasons = [], {}
    for run in range(data.n_runs):
        try:
            kept.append(run_cps(data, run, solver, false_alarm_rate=0.02).parent)
        except ConsistencyError as error:
            reasons[run] = error.reason
    assert res.rejected_runs == tuple(reasons)
    assert res.rejected_reasons == tuple(reasons.values())
    assert set(reasons.values()) == {
        FailureReason.INCONSISTENT_MARKER,
        FailureReason.INCONSISTENT_CHILDREN,
    }
    truth = np.delete(data.parent_truth[:, -1], list(reasons), axis=0)
    np.testing.assert_allclose(
        res.position_error, [p.translation for p in kept] - truth[:, 1:], rtol=0, atol=1e-12
    )
    np.testing.assert_allclose(res.covariance, [p.covariance for p in kept], rtol=1e-9, atol=0)


def test_one_run_is_a_full_cps_record():
    cfg = LeapfrogConfig()
    data = simulate_leapfrog(cfg, 1, np.random.default_rng(0))
    seq = run_cps(data, 0, "wls")
    assert cfg.n_steps == 17
    assert len(seq.steps) == 2 * 17
    assert seq.steps[-1].kind is StepKind.PARENT_MOVED
    # the truth has the geometry of the formation
    np.testing.assert_allclose(data.parent_truth[0, -1, 1], 85.0, atol=0.2)
    assert np.all(np.diff(data.children_truth[0, :, 0, 0]) > 4.0)
    # measured reference points are where the truth says (within a few mm)
    from twin.localization.planar import level2world

    truth = data.parent_truth[0]
    for k in (0, 16):
        world = level2world(data.after[0, k], truth[k + 1, 0], truth[k + 1, 1:])
        np.testing.assert_allclose(world, data.children_truth[0, k], atol=0.01)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"step_length": 4.0}, "whole number of steps"),
        ({"max_tilt": 500 * ARCSEC}, "working range"),
        ({"near_gap": 1.0}, "minimum range"),
        ({"formation": "in_line"}, "Formation"),
        ({"route_length": -1.0}, "route_length"),
        ({"stop_sigma": -0.01}, "stop_sigma"),
        ({"heading_sigma": float("nan")}, "heading_sigma"),
        ({"child_heading_sigma": -1e-3}, "child_heading_sigma"),
        ({"child_spacing": 0.0}, "child_spacing"),
        ({"stagger": -0.1}, "stagger"),
        ({"half_width": 0.0}, "half_width"),
        ({"max_tilt": -1e-6}, "max_tilt"),
    ],
)
def test_config_rejects_bad_values(kwargs, match):
    with pytest.raises(ValueError, match=match):
        LeapfrogConfig(**kwargs)
