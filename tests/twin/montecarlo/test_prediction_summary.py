"""The covariance propagation to a camera, the summary statistics and the budget, checked
on numbers whose answer is known."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from twin.montecarlo import ALL, COLUMNS
from twin.montecarlo.prediction import camera_position_covariance
from twin.montecarlo.summary import budget, distribution, parent_summary, visit_summary


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**31))
def test_camera_covariance_matches_rigidly_moved_cameras(seed):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(4, 4))
    scale = np.diag([1e-3, 5e-3, 5e-3, 5e-3])  # 1 mrad, 5 mm
    p = scale @ (a @ a.T / 4.0) @ scale
    t = rng.uniform(-20, 20, 3)
    c = rng.uniform(-20, 20, 3)
    # Move the camera rigidly with sampled pose errors (small: first order holds).
    d = rng.multivariate_normal(np.zeros(4), p, size=20000)
    lever = c - t
    cy, sy = np.cos(d[:, 0]), np.sin(d[:, 0])
    moved = np.stack(
        [cy * lever[0] - sy * lever[1], sy * lever[0] + cy * lever[1], np.full(len(d), lever[2])],
        axis=1,
    )
    samples = moved + t + d[:, 1:] - c
    expected = camera_position_covariance(p, t, c)
    # Sampling error of each element is about max / sqrt(N) = 0.7 % of the largest.
    np.testing.assert_allclose(np.cov(samples.T), expected, rtol=0.05, atol=0.03 * expected.max())


def test_camera_covariance_of_a_pure_yaw_error_grows_with_the_lever():
    p = np.zeros((4, 4))
    p[0, 0] = 1e-6  # 1 mrad
    cov = camera_position_covariance(p, [0, 0, 0], [10.0, 0.0, 5.0])
    # 10 m sideways lever: 10 mm across it, nothing along it or up.
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), [0.0, 0.01, 0.0], atol=1e-12)


def test_distribution_of_known_values_ignores_nan():
    d = distribution([*range(1, 101), math.nan])
    assert d["n"] == 100
    assert d["median"] == pytest.approx(50.5)
    assert d["p90"] == pytest.approx(90.1)
    assert d["rms"] == pytest.approx(math.sqrt(sum(i * i for i in range(1, 101)) / 100))
    assert math.isnan(distribution([])["median"])


def _rows(config: str, errors: list[float], **extra) -> list[dict]:
    rows = []
    for i, e in enumerate(errors):
        r = {c: (math.nan if k is float else 0 if k is int else "") for c, k in COLUMNS.items()}
        r.update(config=config, trial=i, seed=i, camera="cam1", visit=1, calibrated=1)
        r.update(position_error_mm=e, distance_travelled_m=10.0, **extra)
        rows.append(r)
    return rows


def test_budget_shares_are_the_sources_mean_squares_over_their_sum():
    rows = _rows(ALL, [5.0, 5.0]) + _rows("distance", [3.0, 3.0]) + _rows("angle", [4.0, 4.0])
    b = budget(rows)
    assert b["sources"] == ["distance", "angle"]
    v = b["visits"][0]
    assert v["share"] == {"distance": pytest.approx(9 / 25), "angle": pytest.approx(16 / 25)}
    assert v["rms_mm"]["angle"] == pytest.approx(4.0)
    assert v["sum_over_all"] == pytest.approx(1.0)
    assert b["overall"]["share"] == v["share"]
    assert budget(_rows(ALL, [1.0])) is None


def test_visit_summary_compares_the_monte_carlo_rms_with_the_prediction():
    rows = _rows(ALL, [3.0, 4.0], predicted_transfer_rms_mm=3.0, predicted_calibration_rms_mm=4.0)
    v = visit_summary(rows)[0]
    assert v["predicted"]["rms_mm"] == pytest.approx(5.0)
    assert v["predicted"]["mc_over_predicted"] == pytest.approx(math.sqrt(12.5) / 5.0)
    assert not v["predicted"]["agrees"]
    assert v["calibrated_fraction"] == 1.0


def test_parent_summary_takes_one_row_per_trial():
    rows = _rows(ALL, [0.0, 0.0], parent_final_dx_mm=1.0, parent_predicted_sx_mm=2.0)
    rows[1]["parent_final_dx_mm"] = -1.0
    rows += [dict(rows[0], visit=2)]  # a second visit of trial 0 must not count twice
    s = parent_summary(rows)
    assert s["trials"] == 2
    assert s["x"]["mc_std_mm"] == pytest.approx(math.sqrt(2.0))
    assert s["x"]["predicted_std_mm"] == pytest.approx(2.0)


def test_a_parent_that_never_moved_has_no_ratio_to_its_prediction():
    # Its predicted spread is 0: the ratio is left out, not a division by zero.
    from twin.montecarlo.summary import parent_summary

    trials = [
        {
            "config": "all",
            "trial": t,
            **{f"parent_final_d{a}_mm": 0.0 for a in "xyz"},
            **{f"parent_predicted_s{a}_mm": 0.0 for a in "xyz"},
            "parent_distance_m": 0.0,
        }
        for t in range(3)
    ]
    out = parent_summary(trials)
    assert out["rms_3d"]["mc_over_predicted"] is None
