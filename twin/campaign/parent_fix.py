"""The parent's fix after it drove (paper Section II.B): it measures the stationary
children and solves its pose, through :mod:`twin.hal`.

A retry starts from the other child, and a parent that cannot see both children steps
aside and measures again (:data:`SIDESTEPS`, recorded as events).
"""

from __future__ import annotations

import math

import numpy as np

from twin.campaign.control_points import ControlPoints
from twin.campaign.drives import Drives
from twin.campaign.plan.clearance import ROBOT_CLEARANCE, robot_fits
from twin.campaign.shooting import oriented_on, same_marker
from twin.instruments.errors import InconsistentChildrenError, TiltOutOfRangeError
from twin.localization.observation import ChildObservation
from twin.localization.pose import ParentPose
from twin.timing import timed

SIDESTEPS = (0.4, -0.8)
"""How the parent steps sideways, one after the other, m, when it cannot fix its pose."""

FIX_ATTEMPTS = 2 + len(SIDESTEPS)
"""Attempts at the parent's fix: twice where it stopped (starting from either child), then
once after each side step."""


class ParentFix(Drives):
    """The parent's fix, for :class:`twin.campaign.travel.Travel` (which provides the
    measurements; the devices, the CPS state, the journal and the map are the drives')."""

    control_points: ControlPoints | None

    def fix_parent(self) -> bool:
        """The parent moved: measure the stationary children, solve its pose. Whether an
        attempt gave a fix (each failed one is recorded)."""
        parent = self.rig.parent
        z = float(self.cps.parent.translation[2])
        for attempt in range(FIX_ATTEMPTS):
            if attempt >= 2 and not self._step_aside(SIDESTEPS[attempt - 2]):
                continue
            odo = parent.odometry()
            guess = ParentPose(odo.yaw, np.array([odo.x, odo.y, z]))
            try:
                self.rig.total_station.read_inclination()
            except TiltOutOfRangeError as exc:  # it stands on a slope: perhaps not aside
                self.journal.failure(exc.reason.value, str(exc), parent.name, attempt=attempt)
                continue
            # A retry starts from the other child: the first one measured orients the aim
            # at the next, and a wrong first one must not spoil every attempt.
            order = self.children if attempt % 2 == 0 else self.children[::-1]
            obs = self._observe_children(order, guess, attempt)
            if len(obs) < 2:
                self.journal.failure(
                    "parent_fix_failed", f"measured {len(obs)} children", robot=parent.name
                )
                continue
            try:
                with timed(self.rig.timings, "solving"):
                    self.cps.parent_moved(obs)
            except InconsistentChildrenError as exc:
                self.journal.failure(
                    "inconsistent_children", str(exc), robot=parent.name, attempt=attempt
                )
                continue
            except ValueError as exc:  # geometry that cannot fix the yaw (children in line)
                self.journal.failure(
                    "parent_fix_failed", str(exc), robot=parent.name, attempt=attempt
                )
                continue
            pose = self.cps.parent
            parent.set_pose(float(pose.translation[0]), float(pose.translation[1]), pose.yaw)
            self.journal.parent_fix(pose, obs)
            if self.control_points is not None:
                self.control_points.sight(pose, parent.name)
            return True
        return False

    def _step_aside(self, step: float) -> bool:
        """A child's prism stays hidden from where the parent stands: CPS solves the
        parent's pose wherever it stands, so it steps aside (if there is room) to measure
        again. Whether it moved."""
        parent = self.rig.parent
        odo = parent.odometry()
        side = np.array([-math.sin(odo.yaw), math.cos(odo.yaw)]) * step
        target = odo.pose[:2] + side
        if not robot_fits(self.space, target[None], ROBOT_CLEARANCE)[0]:
            return False
        self.journal.event(
            "parent_stepped_aside", f"{step:+.1f} m to see the children", parent.name
        )
        self._go(parent, target, odo.yaw)
        return True

    def _observe_children(
        self, order: list[str], guess: ParentPose, attempt: int
    ) -> list[ChildObservation]:
        """Each child measured from the parent's guessed pose, the guess oriented on the
        first found; a child whose shots found another's marker is left out."""
        obs: list[ChildObservation] = []
        for child in order:
            o = self.measure(child, guess)
            if o is None:
                continue
            seen = next((p for p in obs if same_marker(p.point_level, o.point_level)), None)
            if seen is not None:
                self.journal.failure(
                    "wrong_child",
                    f"{child}'s shots found {seen.child}'s marker again",
                    robot=child,
                    attempt=attempt,
                )
                continue
            obs.append(o)
            guess = oriented_on(guess, self.cps.child_position(child)[0], o.point_level)
        return obs
