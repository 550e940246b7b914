"""Chi-square consistency tests: when redundant measurements disagree beyond their noise.

A test computes ``chi2 = e^T C^-1 e`` from a vector ``e`` of redundant quantities that are
zero for consistent data (side lengths of the marker triangle against the assembly's, the
CPS residuals) and its predicted covariance ``C``. For Gaussian noise ``chi2`` follows a
chi-square law with ``dof = len(e)`` degrees of freedom; the test fails when it exceeds the
upper ``false_alarm_rate`` quantile of that law, so consistent data fail it with that
probability (default :data:`DEFAULT_FALSE_ALARM_RATE`, 1e-4: about one step in 10 000;
a campaign that catches the error and measures again loses little). ``None`` as the rate
switches a test off.

Every predicted standard deviation gets a numerical floor, :data:`NUMERICAL_FLOOR`, so that
noise-free data (zero covariance) are tested too: a mismatch of more than a few nanometres
is then inconsistent.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.stats import chi2 as chi2_law

from twin.instruments.errors import ConsistencyError

DEFAULT_FALSE_ALARM_RATE = 1e-4
"""Probability that consistent data fail a consistency test."""

NUMERICAL_FLOOR = 1e-9
"""Floor on the predicted standard deviation of every tested quantity, m."""


def check_false_alarm_rate(rate: float | None) -> float | None:
    """Return a false-alarm rate in (0, 1) or None (test off), or raise ValueError."""
    if rate is None:
        return None
    if not (math.isfinite(rate) and 0.0 < rate < 1.0):
        raise ValueError(f"false_alarm_rate must be in (0, 1) or None, got {rate}")
    return float(rate)


@lru_cache(maxsize=256)
def chi2_threshold(dof: int, false_alarm_rate: float) -> float:
    """Upper ``false_alarm_rate`` quantile of the chi-square law with ``dof`` degrees."""
    if dof < 1:
        raise ValueError(f"dof must be at least 1, got {dof}")
    return float(chi2_law.isf(check_false_alarm_rate(false_alarm_rate), dof))


def chi2_statistic(residual: ArrayLike, covariance: ArrayLike) -> float:
    """``e^T (C + floor^2 I)^-1 e`` for a (k,) residual and its (k, k) covariance."""
    return float(chi2_statistic_batch(residual, covariance))


def raise_if_inconsistent(
    chi2: float,
    dof: int,
    false_alarm_rate: float | None,
    error: type[ConsistencyError],
    what: str,
    **details: Any,
) -> None:
    """Raise ``error`` if ``chi2`` exceeds the chi-square quantile (no-op for rate None).

    ``what`` opens the message (e.g. "child 'c1': the three cubes do not fit the marker").
    """
    if false_alarm_rate is None:
        return
    threshold = chi2_threshold(dof, false_alarm_rate)
    if not chi2 <= threshold:  # also catches NaN
        raise error(
            f"{what}: chi2 = {chi2:.4g} on {dof} degrees of freedom exceeds {threshold:.4g} "
            f"(false-alarm rate {false_alarm_rate:g})",
            chi2=float(chi2),
            dof=int(dof),
            threshold=threshold,
            false_alarm_rate=false_alarm_rate,
            **details,
        )


def chi2_statistic_batch(residuals: ArrayLike, covariances: ArrayLike) -> NDArray[np.float64]:
    """:func:`chi2_statistic` of (..., k) residuals with their (..., k, k) covariances -> (...,).

    Each statistic is computed from its own residual and covariance alone (the same
    arithmetic for any trial axes, one small solve per statistic).
    """
    e = np.asarray(residuals, dtype=float)
    k = e.shape[-1]
    c = np.asarray(covariances, dtype=float) + NUMERICAL_FLOOR**2 * np.eye(k)
    # A (1, k) @ (k, 1) product per statistic: the dot product chi2_statistic takes.
    return (e[..., None, :] @ np.linalg.solve(c, e[..., None]))[..., 0, 0]


def exceeds_threshold(
    chi2: ArrayLike, dof: int, false_alarm_rate: float | None
) -> NDArray[np.bool_]:
    """(...,) chi-square values -> (...,) True where :func:`raise_if_inconsistent` would
    raise: above the quantile at ``false_alarm_rate``, or NaN; all False for rate None."""
    values = np.asarray(chi2, dtype=float)
    if false_alarm_rate is None:
        return np.zeros(values.shape, dtype=bool)
    return ~(values <= chi2_threshold(dof, false_alarm_rate))
