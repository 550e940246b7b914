"""Comparing two Monte-Carlo tables: the ratio of medians, its bootstrap interval, and the
chance that a few seeds of one distribution fail a factor band."""

import numpy as np
import pytest

from twin.montecarlo.compare import (
    batch_disagreement,
    errors_by_trial,
    errors_by_visit,
    median_ratio,
    rms_ratio,
    visit_rms_ratio,
)


def _trials(n: int, scale: float, seed: int) -> list[np.ndarray]:
    """Heavy-tailed errors like the hall's: 5 visits a trial, a trial-wide factor."""
    rng = np.random.default_rng(seed)
    return [scale * rng.lognormal(0.0, 0.3) * rng.rayleigh(10.0, 5) for _ in range(n)]


def test_rows_group_by_trial_and_skip_what_was_not_calibrated():
    rows = [
        {"config": "all", "trial": 1, "calibrated": 1, "position_error_mm": 3.0},
        {"config": "all", "trial": 0, "calibrated": 1, "position_error_mm": 1.0},
        {"config": "all", "trial": 0, "calibrated": 0, "position_error_mm": float("nan")},
        {"config": "distance", "trial": 0, "calibrated": 1, "position_error_mm": 9.0},
        {"config": "all", "trial": 0, "calibrated": 1, "position_error_mm": 2.0},
    ]
    got = errors_by_trial(rows)
    assert [t.tolist() for t in got] == [[1.0, 2.0], [3.0]]


def test_the_interval_covers_the_true_ratio_and_excludes_a_wrong_one():
    same = median_ratio(_trials(40, 1.0, 1), _trials(40, 1.0, 2))
    assert same.low < 1.0 < same.high
    double = median_ratio(_trials(40, 1.0, 3), _trials(40, 2.0, 4))
    assert double.low < 2.0 < double.high
    assert double.low > 1.5
    assert double.ratio == pytest.approx(double.median_b / double.median_a)


def test_the_rms_ratio_covers_the_true_ratio_and_its_spread_shrinks_with_trials():
    # Gaussian errors of sigma 1 and 1.3: the RMS ratio is 1.3; its bootstrap spread is
    # that of a ratio of two RMS of n values each, about sqrt(2 / (2 n)) / 1 relative.
    rng = np.random.default_rng(7)
    a = [rng.normal(0.0, 1.0, 1) for _ in range(2000)]
    b = [rng.normal(0.0, 1.3, 1) for _ in range(2000)]
    r = rms_ratio(a, b)
    assert r.low < 1.3 < r.high
    assert r.ratio == pytest.approx(r.rms_b / r.rms_a)
    expected = 1.3 * np.sqrt(1.0 / 2000)  # sqrt(2 * (1 / (2 n)))
    assert r.std == pytest.approx(expected, rel=0.15)
    few = rms_ratio(a[:100], b[:100])
    assert few.std > 3 * r.std
    with pytest.raises(ValueError, match="at least two trials"):
        rms_ratio(a[:1], b)


def test_few_seeds_of_one_distribution_often_fail_a_factor_band():
    trials = _trials(60, 1.0, 5)
    few, (lo, hi) = batch_disagreement(trials, 3, 1.5)
    many, _ = batch_disagreement(trials, 20, 1.5)
    assert lo < 1.0 < hi
    assert few > 0.05  # three seeds: a band of 1.5 fails often for identical distributions
    assert many < few


def test_bad_inputs_are_refused():
    with pytest.raises(ValueError, match="at least two trials"):
        median_ratio([np.ones(3)], _trials(5, 1.0, 0))
    with pytest.raises(ValueError, match="two batches of 4 need 8 trials"):
        batch_disagreement(_trials(5, 1.0, 0), 4, 1.5)


def _by_seed(errors: np.ndarray, first_seed: int = 0) -> dict[int, float]:
    return {first_seed + k: float(e) for k, e in enumerate(errors)}


def test_visits_group_by_camera_and_visit_keyed_by_seed():
    nan = float("nan")
    rows = [
        {"config": "all", "seed": 11, "camera": "cam1", "visit": 0, "calibrated": 1, "e": 1.0},
        {"config": "all", "seed": 11, "camera": "cam2", "visit": 1, "calibrated": 1, "e": 2.0},
        {"config": "all", "seed": 12, "camera": "cam1", "visit": 0, "calibrated": 0, "e": nan},
        {"config": "all", "seed": 13, "camera": "cam1", "visit": 0, "calibrated": 1, "e": 3.0},
        {"config": "angle", "seed": 13, "camera": "cam1", "visit": 0, "calibrated": 1, "e": 9.0},
    ]
    got = errors_by_visit(rows, column="e")
    assert got == {("cam1", 0): {11: 1.0, 13: 3.0}, ("cam2", 1): {11: 2.0}}


@pytest.mark.parametrize("paired", [True, False])
def test_a_change_that_keeps_the_distribution_agrees(paired):
    # The same distribution before and after (independent draws, so the interval has its
    # full width): the true RMS ratio is 1.
    rng = np.random.default_rng(3)
    before, after = rng.rayleigh(10.0, (2, 1000))
    got = visit_rms_ratio(_by_seed(before), _by_seed(after, 0 if paired else 5000), 2000)
    assert got.paired is paired
    assert got.agrees
    # The interval's half width is about that of a ratio of two RMS of n Rayleigh errors
    # (e^2 exponential: each RMS has a relative spread of 1 / (2 sqrt(n))).
    half = 1.96 * np.sqrt(2.0) / (2.0 * np.sqrt(1000))
    assert 0.7 * half < 0.5 * (got.high - got.low) < 1.4 * half


def test_a_change_of_twenty_percent_is_told_apart():
    rng = np.random.default_rng(4)
    before, after = rng.rayleigh(10.0, (2, 1000))
    got = visit_rms_ratio(_by_seed(before), _by_seed(1.2 * after), 2000)
    assert not got.agrees
    assert got.low < 1.2 < got.high
    assert got.ratio == pytest.approx(got.rms_after / got.rms_before)


def test_pairing_by_seed_narrows_the_interval_of_a_small_change():
    # After = before scaled by 1.03 with 1 % of noise per trial: apart, 200 trials cannot
    # tell 3 % from nothing; paired by seed they can.
    rng = np.random.default_rng(5)
    before = rng.rayleigh(10.0, 200)
    after = 1.03 * before * (1.0 + 0.01 * rng.standard_normal(200))
    paired = visit_rms_ratio(_by_seed(before), _by_seed(after), 2000)
    apart = visit_rms_ratio(_by_seed(before), _by_seed(after, 1000), 2000)
    assert paired.paired
    assert not apart.paired
    assert not paired.agrees
    assert paired.low < 1.03 < paired.high
    assert apart.agrees


def test_unchanged_errors_agree_with_no_spread():
    errors = _by_seed(np.arange(1.0, 6.0))
    got = visit_rms_ratio(errors, dict(errors))
    assert (got.ratio, got.low, got.high, got.agrees) == (1.0, 1.0, 1.0, True)


def test_too_few_errors_are_refused_with_the_counts():
    with pytest.raises(ValueError, match="at least two errors before and after, got 1 and 3"):
        visit_rms_ratio({1: 1.0}, {2: 1.0, 3: 2.0, 4: 3.0})
