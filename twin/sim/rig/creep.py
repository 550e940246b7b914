"""The children's creep: a standing child's prisms move a little while the parent drives.

A child on pneumatic tyres with its prisms 1.4 m up a mast does not stand perfectly still
for the half minute the parent takes to drive to its next station: its tyres settle and its
mast leans a milliradian or two. The parent measures the child before and after its drive
(the two halves of a CPS step), so that movement goes straight into the parent's new pose;
the LED data, where the parent stands still, does not see it. Modelled as a horizontal shift
of each standing child, drawn once per leg of the parent (at its first drive after it fixed
its pose: a leg around a corner is several drives, and one creep), as CPS allows for it
(``noise.child_creep_m``; the campaign's ``campaign.child_creep_m``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from twin.hal.devices import MobileBase
from twin.hal.readings import DriveResult
from twin.hal.wrappers import MobileBaseWrapper
from twin.sim.world import World


class CreepingChildren(MobileBaseWrapper):
    """The parent's base: after its first drive since its pose was last set (a CPS fix),
    every child is shifted in the world by a horizontal offset with standard deviation
    ``sigma_m`` on each axis, m.

    Args:
        inner: the parent's base. world: the world the children stand in.
        children: the children's names. sigma_m: the creep, m. rng: its random stream.
    """

    def __init__(
        self,
        inner: MobileBase,
        world: World,
        children: Sequence[str],
        sigma_m: float,
        rng: np.random.Generator,
    ) -> None:
        super().__init__(inner)
        self.world = world
        self.children = tuple(children)
        self.sigma_m = float(sigma_m)
        self.rng = rng
        self._leg_started = False

    def drive_to(self, goal_xy: ArrayLike, goal_yaw: float | None = None) -> DriveResult:
        result = self.inner.drive_to(goal_xy, goal_yaw)
        if not self._leg_started:
            self._leg_started = True
            for child in self.children:
                self.world.shift(child, self.sigma_m * self.rng.standard_normal(2))
        return result

    def set_pose(self, x: float, y: float, yaw: float) -> None:
        self.inner.set_pose(x, y, yaw)
        self._leg_started = False  # a fix: the next drive starts a leg
