"""Weighted least-squares CPS: exact recovery, agreement with the closed form,
consistency, poor geometry, bad input."""

import warnings

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from calib.rotation import wrap_angle
from tests.twin.localization.helpers import iso_cov, measure_from
from twin.localization.closed_form import solve_closed_form
from twin.localization.input_checks import ConvergenceWarning, PoorGeometryWarning
from twin.localization.pose import ParentPose
from twin.localization.wls import solve_wls

coords = st.floats(-50.0, 50.0)
point = st.tuples(coords, coords, st.floats(-2.0, 2.0))


@settings(max_examples=100, deadline=None)
@given(
    st.floats(-np.pi, np.pi, exclude_max=True),
    point,
    st.lists(point, min_size=2, max_size=5),
)
def test_noise_free_recovers_the_exact_pose(yaw, translation, children):
    world = np.array(children)
    assume(np.ptp(world[:, 0]) + np.ptp(world[:, 1]) >= 0.2)
    t = np.array(translation)
    level = measure_from(yaw, t, world)
    n = len(children)
    sol = solve_wls(world, level, np.eye(3 * n) * 1e-6, iso_cov(n, 1e-3))
    assert np.angle(np.exp(1j * (sol.pose.yaw - yaw))) == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(sol.pose.translation, t, atol=1e-8)
    assert sol.chi2 == pytest.approx(0.0, abs=1e-10)
    assert sol.dof == 3 * n - 4
    if n == 2:
        cf = solve_closed_form(world, level)
        # One angle, however each solver wraps it (pi and -pi are the same heading).
        assert abs(wrap_angle(sol.pose.yaw - cf.pose.yaw)) <= 1e-9
        np.testing.assert_allclose(sol.pose.translation, cf.pose.translation, atol=1e-8)


def test_covariance_and_chi2_match_monte_carlo():
    rng = np.random.default_rng(3)
    yaw, t = -0.6, np.array([3.0, 4.0, 0.1])
    world = np.array([[12.0, 3.0, 0.6], [15.0, -2.0, 0.5], [8.0, 6.0, 0.7]])
    level = measure_from(yaw, t, world)
    a = rng.normal(size=(9, 9)) * 1e-3
    cov_w = a @ a.T + np.eye(9) * 1e-6  # correlated world estimates
    cov_m = np.array([np.diag([4e-6, 1e-6, 2e-6])] * 3)
    lw = np.linalg.cholesky(cov_w)
    n = 1500
    errors = np.empty((n, 4))
    chi2 = np.empty(n)
    for i in range(n):
        w = world + (lw @ rng.standard_normal(9)).reshape(3, 3)
        m = level + rng.normal(size=(3, 3)) * np.sqrt(np.diagonal(cov_m, axis1=1, axis2=2))
        sol = solve_wls(w, m, cov_w, cov_m)
        errors[i] = [np.angle(np.exp(1j * (sol.pose.yaw - yaw))), *(sol.pose.translation - t)]
        chi2[i] = sol.chi2
    predicted = solve_wls(world, level, cov_w, cov_m).pose.covariance
    nees = np.einsum("ni,ni->n", errors, np.linalg.solve(predicted, errors.T).T)
    assert nees.mean() == pytest.approx(4.0, abs=0.4)  # 4 dof, standard error 0.07
    assert chi2.mean() == pytest.approx(5.0, abs=0.5)  # 3N - 4 = 5 dof


def test_weights_favour_the_precise_child():
    # Three children, one much noisier: WLS beats an unweighted fit on average.
    rng = np.random.default_rng(12)
    world = np.array([[10.0, 2.0, 0.5], [14.0, -3.0, 0.5], [6.0, -5.0, 0.5]])
    sig = np.array([1e-3, 1e-3, 3e-2])
    cov_m = np.array([np.eye(3) * s**2 for s in sig])
    cov_w = np.eye(9) * 1e-12
    err_w, err_u = [], []
    for _ in range(300):
        m = measure_from(0.0, np.zeros(3), world) + rng.normal(size=(3, 3)) * sig[:, None]
        err_w.append(np.linalg.norm(solve_wls(world, m, cov_w, cov_m).pose.translation))
        # equal weights understate child 3's noise on purpose: no consistency test
        unweighted = solve_wls(world, m, cov_w, iso_cov(3, 1e-3), false_alarm_rate=None)
        err_u.append(np.linalg.norm(unweighted.pose.translation))
    assert np.mean(err_w) < 0.5 * np.mean(err_u)


def test_poor_geometry_is_reported_with_the_predicted_yaw_std():
    world = np.array([[10.0, 0.0, 0.5], [10.0, 0.05, 0.5]])  # 5 cm apart across the line
    level = measure_from(0.0, np.zeros(3), world)
    with pytest.warns(PoorGeometryWarning, match=r"predicted yaw standard deviation") as rec:
        sol = solve_wls(world, level, np.eye(6) * 1e-6, iso_cov(2, 1e-3))
    assert sol.yaw_std > 0.02
    assert f"{sol.yaw_std:.3g}" in str(rec[0].message)
    # A good geometry gives no warning and a small predicted yaw std.
    good = np.array([[5.0, 0.2, 0.5], [10.0, -0.2, 0.5]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sol = solve_wls(
            good, measure_from(0.0, np.zeros(3), good), np.eye(6) * 1e-8, iso_cov(2, 1e-4)
        )
    assert sol.yaw_std < 1e-3
    assert sol.baseline == pytest.approx(np.hypot(5.0, 0.4))


def test_bad_input():
    w = np.array([[10.0, 0.0, 0.0], [12.0, 1.0, 0.0]])
    cw, cm = np.eye(6) * 1e-6, iso_cov(2, 1e-3)
    with pytest.raises(ValueError, match="at least two children"):
        solve_wls(w[:1], w[:1], np.eye(3) * 1e-6, iso_cov(1, 1e-3))
    with pytest.raises(ValueError, match="coincide"):
        solve_wls(np.array([w[0], w[0]]), w, cw, cm)
    bad = w.copy()
    bad[0, 2] = np.inf
    with pytest.raises(ValueError, match="NaN or inf"):
        solve_wls(w, bad, cw, cm)
    with pytest.raises(ValueError, match="2 children but children_level has 3"):
        solve_wls(w, np.vstack([w, [[1.0, 2.0, 3.0]]]), cw, cm)
    with pytest.raises(ValueError, match="positive definite"):
        solve_wls(w, w, np.zeros((6, 6)), np.zeros((2, 3, 3)))
    with pytest.raises(ValueError, match="cov_measurements"):
        solve_wls(w, w, cw, np.eye(3))
    with pytest.raises(ValueError, match="symmetric"):
        solve_wls(w, w, np.triu(np.ones((6, 6))), cm)


def test_children_on_one_vertical_line_leave_the_yaw_unobservable():
    w = np.array([[10.0, 0.0, 0.0], [12.0, 1.0, 0.0]])
    stacked = np.array([[10.0, 0.0, 0.0], [10.0, 0.0, 1.0]])
    with pytest.raises(ValueError, match="yaw is unobservable"):
        solve_wls(w, stacked, np.eye(6) * 1e-6, iso_cov(2, 1e-3))
    with pytest.raises(ValueError, match="yaw is unobservable"):
        solve_wls(stacked, w, np.eye(6) * 1e-6, iso_cov(2, 1e-3))


def test_covariances_must_be_positive_semidefinite():
    w = np.array([[10.0, 0.0, 0.0], [12.0, 1.0, 0.0]])
    with pytest.raises(ValueError, match="cov_children_world is not positive semidefinite"):
        solve_wls(w, w, -np.eye(6), iso_cov(2, 1e-3))
    with pytest.raises(ValueError, match="cov_measurements is not positive semidefinite"):
        solve_wls(w, w, np.eye(6) * 1e-6, -iso_cov(2, 1e-3))
    with pytest.raises(ValueError, match="parent pose's covariance"):
        ParentPose(0.0, np.zeros(3), -np.eye(4))


def test_stopping_at_the_iteration_limit_is_reported():
    rng = np.random.default_rng(4)
    world = np.array([[10.0, 2.0, 0.5], [14.0, -3.0, 0.5], [6.0, -5.0, 0.5]])
    sig = np.array([1e-3, 1e-3, 3e-2])
    cov_m = np.array([np.eye(3) * s**2 for s in sig])
    level = measure_from(0.1, np.zeros(3), world) + rng.normal(size=(3, 3)) * sig[:, None]
    with pytest.warns(ConvergenceWarning, match="did not converge in 1 Gauss-Newton"):
        sol = solve_wls(world, level, np.eye(9) * 1e-8, cov_m, max_iterations=1)
    assert not sol.converged
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sol = solve_wls(world, level, np.eye(9) * 1e-8, cov_m)
    assert sol.converged
    assert sol.iterations < 20
    with pytest.raises(ValueError, match="max_iterations"):
        solve_wls(world, level, np.eye(9) * 1e-8, cov_m, max_iterations=0)
