"""Which trials of a batch a step runs for, and records of (T, ...) arrays read and written
for some of them only (a batch's trials may go their own ways)."""

from __future__ import annotations

from dataclasses import fields, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

Rows = NDArray[np.intp] | slice
"""Which trials a step runs for: all of them (``slice(None)``) or an index array."""

ALL: slice = slice(None)


def picked(rows: Rows) -> NDArray[np.intp] | None:
    """The rows of the trials' draws (:meth:`twin.batch.streams.Draws.take`): None for
    every trial."""
    return None if isinstance(rows, slice) else rows


def take(value: Any, rows: NDArray[np.intp]) -> Any:
    """A dataclass of (T, ...) arrays (or an array) for the trials ``rows`` only."""
    if isinstance(value, np.ndarray):
        return value[rows]
    return replace(value, **{f.name: getattr(value, f.name)[rows] for f in fields(value)})


def put(old: Any, rows: NDArray[np.intp], new: Any, trials: int) -> Any:
    """``old`` (a dataclass of (T, ...) arrays, an array, or None: blank) with the trials
    ``rows`` taken from ``new``; a new object, ``old`` is left as it was."""
    if isinstance(new, np.ndarray):
        out = blank(new, trials) if old is None else np.array(old, copy=True)
        out[rows] = new
        return out
    return replace(
        new,
        **{
            f.name: put(
                None if old is None else getattr(old, f.name), rows, getattr(new, f.name), trials
            )
            for f in fields(new)
        },
    )


def blank_rows(value: Any, n: int) -> Any:
    """A dataclass of arrays like ``value`` for ``n`` trials that have filled nothing."""
    return replace(value, **{f.name: blank(getattr(value, f.name), n) for f in fields(value)})


def blank(like: NDArray[Any], trials: int) -> NDArray[Any]:
    """(T, ...) an array like ``like``'s rows that no trial has filled: NaN, 0 or False."""
    fill: Any = np.nan if np.issubdtype(like.dtype, np.floating) else 0
    return np.full((trials, *like.shape[1:]), fill, dtype=like.dtype)
