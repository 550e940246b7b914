"""Exact duplicate correspondences: rows with the same x, y, z, u and v.

An exact copy of a row is a copy, not a second measurement: two detections of an LED carry
independent pixel noise and never agree to every digit, nor do two surveys of its position.
Counted twice, a copied row enters the fit twice, and the residual variance and the
covariance (J^T J)^-1 treat it as twice the evidence, so every reported standard deviation
shrinks (by sqrt(2) when every row is doubled) with no new information. The calibrations
therefore merge exact duplicates (keep the first of each) unless told to keep them, and
count them in their notes either way.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def duplicate_rows(points_3d: NDArray[np.float64], pixels: NDArray[np.float64]) -> NDArray:
    """(N,) bool: True where a correspondence repeats an earlier one exactly.

    Args:
        points_3d: (N, 3) world points, m. pixels: (N, 2) pixels, px.

    Returns:
        (N,) mask; the first of each group of equal rows is False. Time O(N log N),
        memory O(N).
    """
    rows = np.column_stack([points_3d, pixels])
    repeat = np.ones(len(rows), dtype=bool)
    if len(rows):
        _, first = np.unique(rows, axis=0, return_index=True)
        repeat[first] = False
    return repeat


def drop_duplicates(
    points_3d: NDArray[np.float64], pixels: NDArray[np.float64], keep: bool = False
) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """Remove the rows that repeat an earlier one exactly, unless ``keep``.

    Args:
        points_3d: (N, 3) world points, m. pixels: (N, 2) pixels, px.
        keep: keep the duplicates (count them only).

    Returns:
        points_3d (M, 3) and pixels (M, 2) in their original order, and the number of
        duplicate rows found (N - M unless ``keep``).
    """
    repeat = duplicate_rows(points_3d, pixels)
    count = int(repeat.sum())
    if keep or not count:
        return points_3d, pixels, count
    return points_3d[~repeat], pixels[~repeat], count


def duplicates_note(count: int, n_rows: int, kept: bool) -> str:
    """The note a calibration attaches when ``count`` of its ``n_rows`` rows are copies."""
    what = (
        f"{count} of the {n_rows} correspondences repeat an earlier one exactly "
        "(same x, y, z, u, v)"
    )
    if kept:
        return (
            f"{what}; they were kept as independent measurements: if they are copies, every "
            "standard deviation is too small"
        )
    return (
        f"{what} and were merged: a copy of a row is not a second measurement, and counting "
        "it twice would shrink every standard deviation"
    )
