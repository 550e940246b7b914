"""The instrument's noise keyed to what a shot measures (common random numbers).

A sequential random stream gives each shot whatever draw comes next, so one extra shot (a
lost lock, a re-aim, a child that turned to show its prisms) changes the noise of every
shot after it. Keyed noise gives the n-th shot at cube c of child k, at the child's e-th
place since the parent's p-th station, the same draw whatever happened before. Two runs with
the same seed, at two fidelities or with two noise configurations, then see the same
instrument errors wherever they measure the same things, and their difference is what
they model differently: the comparison is tight at a handful of seeds.

A *place* is counted when a robot is found more than :data:`MOVED` from where it stood at
its last counted place (its base on the floor, so that a child turning on the spot keeps
its place); robots that stop a few centimetres apart at the two fidelities count the same
places.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

MOVED = 0.10
"""A robot found farther than this from its last counted place has moved to a new one, m.
Below the closest spacing of the campaign's data points, above the few centimetres by
which a robot's stop differs between the fidelities."""

SHOT_STREAM = 5
"""Spawn key of the keyed shot noise (the world uses 1, the camera sensors 2, the rig 3,
the marker surveying 4)."""


class _Places:
    """Counts the places a robot has stood at."""

    def __init__(self) -> None:
        self.count = -1
        self._at = np.full(2, np.inf)

    def of(self, xy: ArrayLike) -> int:
        p = np.asarray(xy, dtype=float).reshape(2)
        if np.hypot(*(p - self._at)) > MOVED:
            self.count += 1
            self._at = p.copy()
        return self.count


class ShotNoise:
    """Random generators of the shots' measurement noise, one per (parent place, child,
    child place, cube, repeat).

    Args:
        seed: the rig's root seed.
        children: number of children.
    """

    def __init__(self, seed: int, children: int) -> None:
        self._entropy = np.random.SeedSequence(int(seed)).entropy
        self._parent = _Places()
        self._children = [_Places() for _ in range(children)]
        self._station = 0
        self._repeats: dict[tuple[int, ...], int] = {}

    def generator(
        self, parent_xy: ArrayLike, child: int, child_xy: ArrayLike, cube: int
    ) -> np.random.Generator:
        """The generator of the next shot at ``cube`` of ``child``.

        Args:
            parent_xy: (2,) the parent's true position on the floor, m.
            child: the child's index. child_xy: (2,) its true position on the floor, m.
            cube: the corner cube's index on the child's assembly.
        """
        station = self._parent.of(parent_xy)
        if station != self._station:
            # Children's places count from each station of the parent: a place one run
            # has and the other has not shifts the keys up to the parent's next move only.
            self._station = station
            self._children = [_Places() for _ in self._children]
        key = (station, child, self._children[child].of(child_xy), cube)
        repeat = self._repeats.get(key, 0)
        self._repeats[key] = repeat + 1
        seq = np.random.SeedSequence(self._entropy, spawn_key=(SHOT_STREAM, *key, repeat))
        return np.random.default_rng(seq)
