"""Small array helpers shared by the instrument models."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray


def matrices(rows: Sequence[Sequence[ArrayLike]], shape: tuple[int, ...]) -> NDArray[np.float64]:
    """(*shape, R, C) matrices from R rows of C entries, each a (*shape) array or a scalar:
    what ``np.stack`` of the rows' stacks gives, filled in place."""
    out = np.empty((*shape, len(rows), len(rows[0])))
    for i, row in enumerate(rows):
        for j, value in enumerate(row):
            out[..., i, j] = value
    return out
