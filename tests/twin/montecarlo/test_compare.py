"""Comparing two Monte-Carlo tables: the ratio of medians, its bootstrap interval, and the
chance that a few seeds of one distribution fail a factor band."""

import numpy as np
import pytest

from twin.montecarlo.compare import batch_disagreement, errors_by_trial, median_ratio, rms_ratio


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
