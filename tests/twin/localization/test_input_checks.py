"""Input checks over trials: the verdict of each matrix, the trial named in the message."""

import numpy as np
import pytest

from twin.localization.input_checks import (
    check_covariance,
    check_covariances,
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
def test_positive_semidefinite_to_the_tolerance(n, relative):
    good = [with_smallest_eigenvalue(n, 0.2, s) for s in range(4)]
    c = np.stack([*good, with_smallest_eigenvalue(n, relative, 9)])
    if relative >= -1e-11:  # the tolerance is 1e-10 of the largest eigenvalue, 1
        assert check_covariances(c, n, "c") is c
        np.testing.assert_array_equal(check_covariance(c[-1], n, "c"), c[-1])
        return
    with pytest.raises(ValueError, match=r"positive semidefinite \(trial 4: smallest"):
        check_covariances(c, n, "c")
    with pytest.raises(ValueError, match=r"c is not positive semidefinite \(smallest eigenvalue"):
        check_covariance(c[-1], n, "c")


def test_zero_covariances_pass_and_bad_ones_name_their_trial():
    zero = np.zeros((3, 3, 3))
    np.testing.assert_array_equal(check_covariances(zero, 3, "c"), zero)
    asym = zero.copy()
    asym[1, 0, 1] = 1.0
    with pytest.raises(ValueError, match=r"symmetric \(trial 1 is not"):
        check_covariances(asym, 3, "c")
    with pytest.raises(ValueError, match="NaN"):
        check_covariances(np.full((2, 3, 3), np.nan), 3, "c")
    with pytest.raises(ValueError, match="shape"):
        check_covariances(np.zeros((2, 3, 4)), 3, "c")
    with pytest.raises(ValueError, match=r"^c must be symmetric$"):
        check_covariance(asym[1], 3, "c")
    with pytest.raises(ValueError, match=r"c must have shape \(3, 3\)"):
        check_covariance(zero, 3, "c")


def test_baseline_and_stand_in():
    rng = np.random.default_rng(1)
    points = rng.uniform(-5, 5, (6, 4, 3))
    baseline = horizontal_baseline_batch(points)
    for i in range(6):
        pairs = [np.hypot(*(p - q)[:2]) for p in points[i] for q in points[i]]
        assert baseline[i] == pytest.approx(max(pairs), rel=1e-15)
    bad = np.array([False, True, False, False, False, True])
    cov = np.zeros((6, 12, 12))
    world, level, cw, cm = substitute_trials(bad, points, points, cov, cov)
    np.testing.assert_array_equal(world[~bad], points[~bad])
    assert np.all(horizontal_baseline_batch(level[bad]) > 1.0)
    assert np.all(np.linalg.eigvalsh(cw[bad]) == 1.0)
    assert np.all(cm[~bad] == 0)
