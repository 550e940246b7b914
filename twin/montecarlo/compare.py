"""Comparing the camera position errors of two Monte-Carlo tables (two fidelities, or one
fidelity before and after a change of the code).

The errors of one trial's calibrations are correlated (they share the parent's track), so
the resampling unit is the trial: the bootstrap draws whole trials with replacement, and
the spread of "a handful of seeds" is that of the medians of two disjoint batches of
trials drawn from one table.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import stats

from twin.montecarlo.sources import ALL


def errors_by_trial(rows: Sequence[dict[str, Any]], config: str = ALL) -> list[np.ndarray]:
    """Each trial's camera position errors, mm, of its calibrated visits (trials in order)."""
    by: dict[int, list[float]] = {}
    for r in rows:
        if r["config"] == config and r["calibrated"] and np.isfinite(r["position_error_mm"]):
            by.setdefault(int(r["trial"]), []).append(float(r["position_error_mm"]))
    return [np.array(by[t]) for t in sorted(by)]


def _median(trials: Sequence[np.ndarray]) -> float:
    return float(np.median(np.concatenate(trials)))


@dataclass(frozen=True)
class MedianRatio:
    """The ratio of two tables' pooled median errors, with a bootstrap interval.

    Attributes:
        median_a, median_b: pooled medians, mm. ratio: median_b / median_a.
        low, high: the bootstrap interval of the ratio (``level``, percentile method).
        trials_a, trials_b: trials with at least one calibration.
    """

    median_a: float
    median_b: float
    ratio: float
    low: float
    high: float
    level: float
    trials_a: int
    trials_b: int


def _check_tables(a: Sequence[np.ndarray], b: Sequence[np.ndarray]) -> None:
    if len(a) < 2 or len(b) < 2:
        raise ValueError(f"need at least two trials in each table, got {len(a)} and {len(b)}")


def _interval(ratios: np.ndarray, level: float) -> tuple[float, float]:
    """The central ``level`` interval of bootstrap ``ratios`` (percentile method)."""
    tail = 0.5 * (1.0 - level)
    low, high = np.quantile(ratios, [tail, 1.0 - tail])
    return float(low), float(high)


def median_ratio(
    a: Sequence[np.ndarray],
    b: Sequence[np.ndarray],
    resamples: int = 4000,
    level: float = 0.95,
    seed: int = 0,
) -> MedianRatio:
    """Ratio of pooled medians, b over a, with a trial-level bootstrap interval.

    Args:
        a, b: per-trial error arrays (:func:`errors_by_trial`), at least two trials each.
        resamples: bootstrap resamples. level: the interval's coverage. seed: its RNG.
    """
    _check_tables(a, b)
    rng = np.random.default_rng(seed)
    ratios = np.empty(resamples)
    for i in range(resamples):
        ia = rng.integers(0, len(a), len(a))
        ib = rng.integers(0, len(b), len(b))
        ratios[i] = _median([b[j] for j in ib]) / _median([a[j] for j in ia])
    low, high = _interval(ratios, level)
    ma, mb = _median(a), _median(b)
    return MedianRatio(ma, mb, mb / ma, low, high, level, len(a), len(b))


@dataclass(frozen=True)
class RmsRatio:
    """The ratio of two tables' RMS errors, with a bootstrap interval.

    Attributes:
        rms_a, rms_b: pooled RMS errors (the tables' unit). ratio: rms_b / rms_a.
        low, high: the bootstrap interval of the ratio (``level``, percentile method).
        std: the bootstrap standard deviation of the ratio.
        trials_a, trials_b: trials with at least one error.
    """

    rms_a: float
    rms_b: float
    ratio: float
    low: float
    high: float
    std: float
    level: float
    trials_a: int
    trials_b: int


def rms_ratio(
    a: Sequence[np.ndarray],
    b: Sequence[np.ndarray],
    resamples: int = 4000,
    level: float = 0.95,
    seed: int = 0,
) -> RmsRatio:
    """Ratio of pooled RMS errors, b over a, with a trial-level bootstrap interval.

    Args:
        a, b: per-trial error arrays (:func:`errors_by_trial`), at least two trials each.
        resamples: bootstrap resamples. level: the interval's coverage. seed: its RNG.
    """
    _check_tables(a, b)
    rng = np.random.default_rng(seed)

    def resampled(trials: Sequence[np.ndarray]) -> tuple[float, np.ndarray]:
        squares = np.array([np.sum(t**2) for t in trials])
        counts = np.array([t.size for t in trials], dtype=float)
        pick = rng.integers(0, len(trials), (resamples, len(trials)))
        rms = np.sqrt(squares[pick].sum(axis=1) / counts[pick].sum(axis=1))
        return float(np.sqrt(squares.sum() / counts.sum())), rms

    ra, boot_a = resampled(a)
    rb, boot_b = resampled(b)
    ratios = boot_b / boot_a
    low, high = _interval(ratios, level)
    return RmsRatio(ra, rb, rb / ra, low, high, float(ratios.std()), level, len(a), len(b))


def batch_disagreement(
    trials: Sequence[np.ndarray], batch: int, factor: float, draws: int = 4000, seed: int = 0
) -> tuple[float, tuple[float, float]]:
    """How often two disjoint batches of ``batch`` trials from one table have medians more
    than ``factor`` apart, and the 95 % range of their ratio.

    This is the chance that a comparison of two *identical* error distributions over
    ``batch`` seeds each fails a ``factor`` band.
    """
    if 2 * batch > len(trials):
        raise ValueError(f"two batches of {batch} need {2 * batch} trials, got {len(trials)}")
    rng = np.random.default_rng(seed)
    ratios = np.empty(draws)
    for i in range(draws):
        order = rng.permutation(len(trials))
        first = [trials[j] for j in order[:batch]]
        second = [trials[j] for j in order[batch : 2 * batch]]
        ratios[i] = _median(first) / _median(second)
    outside = float(np.mean((ratios > factor) | (ratios < 1.0 / factor)))
    lo, hi = np.quantile(ratios, [0.025, 0.975])
    return outside, (float(lo), float(hi))


def errors_by_visit(
    rows: Sequence[dict[str, Any]], column: str = "position_error_mm", config: str = ALL
) -> dict[tuple[str, int], dict[int, float]]:
    """Each planned visit's errors (``column``, the table's unit) by trial seed, of the
    trials that calibrated it: ``{(camera, visit): {seed: error}}``, visits in table order."""
    out: dict[tuple[str, int], dict[int, float]] = {}
    for r in rows:
        if r["config"] != config:
            continue
        errors = out.setdefault((str(r["camera"]), int(r["visit"])), {})
        if r["calibrated"] and np.isfinite(r[column]):
            errors[int(r["seed"])] = float(r[column])
    return out


@dataclass(frozen=True)
class VisitRatio:
    """The RMS errors of one visit before and after a change, and their ratio.

    Attributes:
        rms_before, rms_after: RMS of the errors (their unit). ratio: after / before.
        low, high: the bootstrap interval of the ratio (``level``, BCa).
        level: the interval's coverage. paired: whether the trials were paired by seed
            (the seeds shared by both tables), or resampled apart.
        trials_before, trials_after: the errors each RMS is of.
    """

    rms_before: float
    rms_after: float
    ratio: float
    low: float
    high: float
    level: float
    paired: bool
    trials_before: int
    trials_after: int

    @property
    def agrees(self) -> bool:
        """Whether the interval holds 1: nothing tells the two distributions apart."""
        return self.low <= 1.0 <= self.high


def _rms_of_ratio(before: np.ndarray, after: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.sqrt(np.mean(after**2, axis=axis) / np.mean(before**2, axis=axis))


def visit_rms_ratio(
    before: dict[int, float],
    after: dict[int, float],
    resamples: int = 9999,
    level: float = 0.95,
    seed: int = 0,
) -> VisitRatio:
    """The ratio of a visit's RMS errors after and before a change, with a bootstrap
    interval (:func:`scipy.stats.bootstrap`, BCa).

    Args:
        before, after: errors by trial seed (:func:`errors_by_visit`). Where at least two
            seeds are shared, only those count and the bootstrap draws pairs of them (the
            same seed sees the same noise, so the interval is far narrower than apart);
            otherwise each table is resampled on its own.
        resamples: bootstrap resamples. level: the interval's coverage. seed: its RNG.

    Raises:
        ValueError: if a table has fewer than two errors.
    """
    shared = sorted(before.keys() & after.keys())
    paired = len(shared) >= 2
    if paired:
        b = np.array([before[s] for s in shared])
        a = np.array([after[s] for s in shared])
    else:
        b = np.array(list(before.values()), dtype=float)
        a = np.array(list(after.values()), dtype=float)
    if len(b) < 2 or len(a) < 2:
        raise ValueError(f"need at least two errors before and after, got {len(b)} and {len(a)}")
    ratio = float(_rms_of_ratio(b, a))
    if np.all(a == b):  # no spread to resample: the change changed nothing here
        low = high = ratio
    else:
        res = stats.bootstrap(
            (b, a),
            _rms_of_ratio,
            n_resamples=resamples,
            paired=paired,
            vectorized=True,
            confidence_level=level,
            method="BCa",
            rng=np.random.default_rng(seed),
        )
        low, high = float(res.confidence_interval.low), float(res.confidence_interval.high)
    rms_b, rms_a = float(np.sqrt(np.mean(b**2))), float(np.sqrt(np.mean(a**2)))
    return VisitRatio(rms_b, rms_a, ratio, low, high, level, paired, len(b), len(a))
