"""Batched input checks: the same verdicts as the scalar checks, trial by trial."""

import numpy as np
import pytest

from twin.localization.input_checks import check_covariance, horizontal_baseline
from twin.localization.input_checks_batch import (
    check_covariances_batch,
    horizontal_baseline_batch,
    substitute_trials,
)


def with_smallest_eigenvalue(n, relative, seed):
    """A symmetric (n, n) matrix with eigenvalues 1 ... and ``relative`` as the smallest."""
    rng = np.random.default_rng(seed)
    q = np.linalg.qr(rng.standard_normal((n, n)))[0]
    eig = np.linspace(1.0, 0.5, n)
    eig[-1] = relative
    c = q @ np.diag(eig) @ q.T
    return 0.5 * (c + c.T)


@pytest.mark.parametrize("relative", [0.3, 0.0, -1e-13, -1e-11, -1e-9, -1e-3])
@pytest.mark.parametrize("n", [3, 6])
def test_positive_semidefinite_as_the_scalar_check(n, relative):
    good = [with_smallest_eigenvalue(n, 0.2, s) for s in range(4)]
    c = np.stack([*good, with_smallest_eigenvalue(n, relative, 9)])
    try:
        check_covariance(c[-1], n, "c")
    except ValueError:
        with pytest.raises(ValueError, match=r"positive semidefinite \(trial 4: smallest"):
            check_covariances_batch(c, n, "c")
    else:
        assert check_covariances_batch(c, n, "c") is not None
        assert relative >= -1e-11  # the scalar tolerance is 1e-10 of the largest


def test_zero_covariances_pass_and_bad_ones_name_their_trial():
    zero = np.zeros((3, 3, 3))
    np.testing.assert_array_equal(check_covariances_batch(zero, 3, "c"), zero)
    asym = zero.copy()
    asym[1, 0, 1] = 1.0
    with pytest.raises(ValueError, match=r"symmetric \(trial 1 is not"):
        check_covariances_batch(asym, 3, "c")
    with pytest.raises(ValueError, match="NaN"):
        check_covariances_batch(np.full((2, 3, 3), np.nan), 3, "c")
    with pytest.raises(ValueError, match="shape"):
        check_covariances_batch(np.zeros((2, 3, 4)), 3, "c")


def test_baseline_and_stand_in():
    rng = np.random.default_rng(1)
    points = rng.uniform(-5, 5, (6, 4, 3))
    baseline = horizontal_baseline_batch(points)
    for i in range(6):
        assert baseline[i] == pytest.approx(horizontal_baseline(points[i]), rel=1e-15)
    bad = np.array([False, True, False, False, False, True])
    cov = np.zeros((6, 12, 12))
    world, level, cw, cm = substitute_trials(bad, points, points, cov, cov)
    np.testing.assert_array_equal(world[~bad], points[~bad])
    assert np.all(horizontal_baseline_batch(level[bad]) > 1.0)
    assert np.all(np.linalg.eigvalsh(cw[bad]) == 1.0)
    assert np.all(cm[~bad] == 0)
