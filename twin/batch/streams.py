"""Each trial's seeded stream of standard normal draws, handed out in a fixed order: a
trial's noise depends on its seed alone, not on its batch, its chunk or its neighbours."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from twin.batch.steps import BatchPlan, Drive, Fix, Place, Point

BATCH_STREAM = 11
"""Spawn key of a trial's stream of the batch fidelity's noise."""

CREEP_BATCH_STREAM = 12
"""Spawn key of a trial's stream of the children's creep (drawn only when there is some)."""


class Draws:
    """Each trial's standard normal draws, handed out in a fixed order.

    Each trial's draws come from its own generator, in blocks; a generator gives the same
    sequence whatever the blocks, so a trial's noise depends on its seed alone, not on the
    batch, the chunk, how far ahead the draws were reserved, or which other trials drew
    at the same time (each trial keeps its own place in its sequence).

    Args:
        seeds: (T,) the trials' root seeds.
        count: draws each trial is expected to need (reserved at once; more are drawn as
            they are needed).
        stream: the spawn key of the trials' generators (a source with its own stream
            changes no other source's draws when it is switched on).
    """

    def __init__(self, seeds: Sequence[int], count: int, stream: int = BATCH_STREAM) -> None:
        self.stream = stream
        self._generators = [self._generator(seed) for seed in seeds]
        self.values = np.zeros((len(seeds), 0))
        self.used = np.zeros(len(seeds), dtype=np.intp)  # each trial's place in values
        self._reserve(count)

    def _generator(self, seed: int) -> np.random.Generator:
        return np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(self.stream,)))

    def _reserve(self, count: int) -> None:
        """Drop the draws taken and draw more: every trial then has ``count`` or more
        ahead (each trial's own sequence goes on where it stopped)."""
        left = self.values.shape[1] - self.used
        width = int(left.max(initial=0)) + count
        self.values = np.stack(
            [
                np.concatenate([row[start:], g.standard_normal(width - ahead)])
                for row, start, ahead, g in zip(
                    self.values, self.used, left, self._generators, strict=True
                )
            ]
        ).reshape(len(self._generators), width)
        self.used = np.zeros(len(self._generators), dtype=np.intp)

    def take(self, *shape: int, rows: NDArray[np.intp] | None = None) -> NDArray[np.float64]:
        """(T, *shape) the next draws of every trial, or (R, *shape) of the trials
        ``rows``."""
        n = math.prod(shape)
        used = self.used if rows is None else self.used[rows]
        if len(used) and int(used.max()) + n > self.values.shape[1]:
            self._reserve(max(n, 4096))
            used = self.used if rows is None else self.used[rows]
        start = int(used[0]) if len(used) else 0
        if rows is None and (used == start).all():
            out = self.values[:, start : start + n]
            self.used = self.used + n
        else:
            picked = np.arange(len(self.values)) if rows is None else rows
            out = self.values[picked[:, None], used[:, None] + np.arange(n)]
            self.used[picked] += n
        return out.reshape(len(used), *shape)

    def restart(self, rows: NDArray[np.intp], seeds: Sequence[int]) -> None:
        """Trials ``rows`` start again from ``seeds`` (their first draws next)."""
        width = self.values.shape[1]
        for k, seed in zip(rows, seeds, strict=True):
            self._generators[k] = self._generator(seed)
            self.values[k] = self._generators[k].standard_normal(width)
            self.used[k] = 0


def draws_needed(plan: BatchPlan, n_leds: int) -> int:
    """How many normal draws one trial of ``plan`` takes."""
    per_shot = 3 + 2  # polar noise, inclination reading
    marker = len(plan.children) * (3 + n_leds) * 3
    count = marker
    for step in plan.steps:
        if isinstance(step, Drive):
            count += 3
        elif isinstance(step, Place):
            count += 3 * per_shot
        elif isinstance(step, Fix):
            count += 3 * per_shot * len(step.children)
        elif isinstance(step, Point):
            count += 2 * n_leds
    return count
