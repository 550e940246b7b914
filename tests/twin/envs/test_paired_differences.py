"""Paired differences against a baseline (``twin strategies --baseline``): synthetic
episodes with a known mean difference, paired by seed."""

from __future__ import annotations

import math
import random
from dataclasses import fields

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from twin.envs.comparison import Episode, paired_difference, paired_differences


def _episode(policy: str, seed: int, true_error_mm: float, errors: dict[str, float]) -> Episode:
    values = {f.name: 0 for f in fields(Episode)}
    values.update(
        policy=policy,
        seed=seed,
        true_error_mm=true_error_mm,
        camera_errors_mm=errors,
        reward=-true_error_mm,
        distance_m=10.0,
    )
    return Episode(**values)


def test_the_interval_covers_a_known_mean_difference_as_often_as_it_says():
    """Per seed a baseline error that varies a lot between sites (sd 30 mm) and a policy
    that differs from it by mu + noise (sd 2 mm): the paired 95 % interval covers mu in
    95 % of repeats (400 repeats: 3.5 binomial sd is 0.038), and is as wide as t's."""
    rng = np.random.default_rng(7)
    mu, sd, n, repeats = -1.5, 2.0, 30, 400
    covered, widths = 0, []
    for _ in range(repeats):
        base = 40.0 + 30.0 * rng.standard_normal(n)
        policy = base + mu + sd * rng.standard_normal(n)
        pairs, mean, low, high = paired_difference(policy, base)
        assert pairs == n
        assert low < mean < high
        covered += low <= mu <= high
        widths.append(high - low)
    assert abs(covered / repeats - 0.95) < 0.038
    # t(0.975, 29) = 2.045; E[s] for n = 30 is 0.991 sd.
    assert np.mean(widths) == pytest.approx(2 * 2.045 * 0.991 * sd / math.sqrt(n), rel=0.05)


@given(st.lists(st.floats(-1e3, 1e3), min_size=2, max_size=40), st.floats(-50, 50))
def test_swapping_the_pair_negates_the_difference(values, shift):
    other = [v + shift * (1 + (k % 3)) for k, v in enumerate(values)]
    n, mean, low, high = paired_difference(values, other)
    n2, mean2, low2, high2 = paired_difference(other, values)
    assert n == n2 == len(values)
    assert mean2 == pytest.approx(-mean, abs=1e-9)
    assert (low2, high2) == pytest.approx((-high, -low), abs=1e-9)


def test_pairs_with_an_undefined_value_are_left_out_and_one_pair_has_no_interval():
    assert paired_difference([1.0, math.nan, 5.0], [0.0, 2.0, 1.0])[:2] == (2, 2.5)
    n, mean, low, high = paired_difference([3.0], [1.0])
    assert (n, mean) == (1, 2.0)
    assert math.isnan(low)
    assert math.isnan(high)
    assert paired_difference([], [])[0] == 0


def test_episodes_are_paired_by_seed_whatever_their_order():
    """The learned policy is 2 mm better than greedy on every seed; greedy's errors vary
    from site to site by far more. In any order the difference is exactly -2 mm."""
    rng = np.random.default_rng(3)
    base = {seed: float(rng.uniform(10, 200)) for seed in range(100, 140)}
    episodes = [_episode("greedy", s, e, {"cam1": e}) for s, e in base.items()]
    episodes += [_episode("learned", s, e - 2.0, {"cam1": e - 2.0}) for s, e in base.items()]
    # One seed where the learned policy calibrated nothing: no camera error to pair.
    episodes.append(_episode("learned", 99, 1000.0, {}))
    episodes.append(_episode("greedy", 99, 12.0, {"cam1": 12.0}))
    random.Random(1).shuffle(episodes)
    found = {d.metric: d for d in paired_differences(episodes, "greedy")}
    truth = found["true_error_mm"]
    assert (truth.policy, truth.baseline, truth.pairs) == ("learned", "greedy", 41)
    assert truth.mean == pytest.approx((40 * -2.0 + 988.0) / 41)
    camera = found["mean_camera_error_mm"]
    assert camera.pairs == 40  # the seed without a calibration is left out
    assert camera.mean == pytest.approx(-2.0)
    assert camera.low == pytest.approx(-2.0)
    assert camera.high == pytest.approx(-2.0)
    assert found["reward"].mean == pytest.approx(-truth.mean)


def test_a_baseline_that_played_nothing_is_named():
    with pytest.raises(ValueError, match="baseline 'greedy' played no episode"):
        paired_differences([_episode("paper", 0, 1.0, {})], "greedy")


def test_bad_pairs_are_refused():
    with pytest.raises(ValueError, match="one length"):
        paired_difference([1.0, 2.0], [1.0])
    with pytest.raises(ValueError, match="confidence"):
        paired_difference([1.0, 2.0], [1.0, 0.0], confidence=1.0)
