"""Travel by CPS (paper Section II.B): a leg's moves executed through :mod:`twin.hal`.

The children drive to their stops one after the other, each measured by the standing
parent as it arrives and placed in the CPS state; the ones placed first are measured again
after the others drove (a child can be pushed, or roll off a ledge). Then the parent drives
and fixes its pose from the stationary children.

Two moves are recoveries, not faults, and are recorded as events: a child whose prism the
parent cannot measure turns on the spot and is measured again (:data:`TURNS_DEG`); a parent
that cannot see both children steps aside and measures again
(:data:`twin.campaign.parent_fix.SIDESTEPS`). A leg that fails all the same is recovered:
the group backs off and the leg is planned again, shorter (:mod:`twin.campaign.recovery`).
The drives themselves, past the robots that stand and off the route, are
:mod:`twin.campaign.drives`; the parent's fix is :mod:`twin.campaign.parent_fix`.
"""

from __future__ import annotations

import math

import numpy as np

from twin.campaign.aborted import CampaignAborted, NoProgress
from twin.campaign.control_points import ControlPoints
from twin.campaign.journal import Journal, RobotJournal
from twin.campaign.parent_fix import FIX_ATTEMPTS, SIDESTEPS
from twin.campaign.recovery import LegRecovery
from twin.campaign.shooting import measure_child, moved_between, same_marker
from twin.campaign.strategy import Leg
from twin.hal.rig import Rig
from twin.instruments.marker import MarkerAssembly
from twin.localization.observation import ChildObservation
from twin.localization.planar import world2level
from twin.localization.pose import ParentPose
from twin.localization.sequence import CpsSequence
from twin.scenario.schema import Space
from twin.timing import timed

TURNS_DEG = (30.0, -60.0)
"""How a child turns, one after the other, when the parent cannot measure all its prisms."""

__all__ = ["FIX_ATTEMPTS", "SIDESTEPS", "CampaignAborted", "NoProgress", "Travel"]


class Travel(LegRecovery):
    """Moves the robots and keeps the CPS state of the group.

    Args:
        rig: the devices. cps: the group's CPS state. journal: the campaign's journal.
        space: the map (for the drives' clearance). marker: the assembly as surveyed.
        lock_retries: further aims after a lost prism lock.
        false_alarm_rate: of the consistency tests (None: no test, a noise-free instrument).
        max_drives: the most drives of all the robots together
            (:attr:`twin.campaign.bounds.CampaignBounds.drives`; None: no bound).
        max_recoveries: the most recoveries of legs in a row (:mod:`twin.campaign.
            recovery`, :attr:`twin.campaign.bounds.CampaignBounds.recoveries`; None: no
            bound).
    """

    def __init__(
        self,
        rig: Rig,
        cps: CpsSequence,
        journal: Journal,
        space: Space,
        marker: MarkerAssembly,
        lock_retries: int,
        false_alarm_rate: float | None,
        max_drives: int | None = None,
        max_recoveries: int | None = None,
    ) -> None:
        self.rig, self.cps, self.journal = rig, cps, journal
        self.max_drives = max_drives
        self.drives = 0  # every robot's, so far
        self.max_recoveries = max_recoveries
        self.recoveries = 0  # of legs in a row, since the last leg that ended with a fix
        self.space, self.marker = space, marker
        self.lock_retries = lock_retries
        self.false_alarm_rate = false_alarm_rate
        self.children = list(rig.children)
        # The measurement that placed each child in the CPS state.
        self.placed: dict[str, ChildObservation] = {}
        # Measured after each fix, when the scenario has any (set by the campaign).
        self.control_points: ControlPoints | None = None

    # -- a leg ---------------------------------------------------------------------------------
    def execute(self, leg: Leg) -> bool:
        """Move the children, then the parent, and fix the parent's pose.

        Returns:
            Whether the parent reached its stop.

        Raises:
            LegRecovered: a child could not be measured at its stop, or the parent could
                not fix its pose after it drove, and the group backed off to a place
                measured before (:mod:`twin.campaign.recovery`): plan the leg again.
            CampaignAborted: it could not back off.
            NoProgress: the recoveries in a row reached their bound.
        """
        order = [move.robot for move in leg.children]
        before = self.cps.parent
        for move in leg.children:
            if not self.drive_along(self.rig.children[move.robot], move):
                self.journal.failure(
                    "child_blocked", "the child stopped short of its stop", move.robot
                )
            if self.place_child_turning(move.robot) is None and self.drive_again(move) is None:
                self.recover_child(move)
        for child in order[:-1]:
            self.check_stayed(child, order[-1])
        reached = self.drive_along(self.rig.parent, leg.parent)
        if not self.fix_parent():
            self.recover_parent(leg, before)
        self.recoveries = 0
        if not reached:
            self.journal.failure(
                "parent_blocked", "the parent stopped short of its goal", robot=self.rig.parent.name
            )
        return reached

    # -- measuring and placing children -------------------------------------------------------
    def measure(self, child: str, parent: ParentPose | None = None) -> ChildObservation | None:
        """The child's observation from the parent's pose (default: its CPS estimate)."""
        return measure_child(
            self.rig.total_station,
            child,
            parent if parent is not None else self.cps.parent,
            self.child_pose(child),
            self.marker,
            self.space.floor_z,
            self.lock_retries,
            RobotJournal(self.journal, child),
            self.false_alarm_rate,
        )

    def _correct_child_pose(self, child: str, obs: ChildObservation, parent: ParentPose) -> None:
        """Correct the child's own localisation from its measured marker pose."""
        if obs.marker_pose is None:
            return
        r = parent.rotation @ obs.marker_pose.rotation
        origin = parent.level2world(obs.marker_pose.translation)
        self.rig.children[child].set_pose(
            float(origin[0]), float(origin[1]), math.atan2(r[1, 0], r[0, 0])
        )

    def place_child(self, child: str) -> ChildObservation | None:
        """Measure a child that moved (the parent stands) and place it in the CPS state;
        None when it could not be measured, or its shots found another child's marker."""
        obs = self.measure(child)
        if obs is None or self._another_marker(child, obs):
            return None
        self._place(child, obs)
        return obs

    def _another_marker(self, child: str, obs: ChildObservation) -> bool:
        """Whether the standing parent's shots at ``child`` found the marker of another
        child, where the CPS state has it (recorded as ``wrong_child``).

        The instrument locks the prism nearest its aim: a child whose prisms are hidden
        (behind a wall, say), seen in nearly the same bearing as another, gives the
        other's marker, which fits the assembly as well as its own. Placed there, the two
        children would be one point, and the parent could not fix its pose from them.
        """
        parent = self.cps.parent
        for other in self.placed:
            if other == child:
                continue
            known = world2level(self.cps.child_position(other)[0], parent.yaw, parent.translation)
            if same_marker(obs.point_level, known):
                self.journal.failure(
                    "wrong_child", f"{child}'s shots found {other}'s marker", robot=child
                )
                return True
        return False

    def _place(self, child: str, obs: ChildObservation) -> None:
        """Place a child measured from the standing parent in the CPS state."""
        with timed(self.rig.timings, "solving"):
            self.cps.children_moved([obs])
        world, _ = self.cps.child_position(child)
        self.journal.child_placed(child, obs.point_level, obs.covariance, world)
        self._correct_child_pose(child, obs, self.cps.parent)
        self.placed[child] = obs

    def place_child_turning(self, child: str) -> ChildObservation | None:
        """:meth:`place_child`; if a prism stays out of reach, the child turns on the spot
        (its reference point is on its mast, the axis it turns about) and is measured
        again."""
        obs = self.place_child(child)
        for turn in TURNS_DEG:
            if obs is not None:
                return obs
            pose = self.child_pose(child)
            self.journal.event("child_turned", f"turning {turn:+.0f} deg to show its prisms", child)
            self._go(self.rig.children[child], pose[:2], pose[2] + math.radians(turn))
            obs = self.place_child(child)
        return obs

    def check_stayed(self, child: str, mover: str) -> None:
        """Measure a placed child again after ``mover`` drove (the parent stands), as a
        surveyor checks a backsight; place it anew if it moved.

        A parked robot can be pushed, or roll off a ledge; if it moved unnoticed, the
        parent's next fix would find the two children inconsistent with no way to tell
        which one moved.
        """
        before = self.placed.get(child)
        if before is None:
            return
        obs = self.measure(child)
        if obs is None:
            self.journal.event(
                "child_unchecked",
                f"{child} not measured after {mover} drove: whether it was pushed is not known",
                child,
            )
            return
        if not moved_between(before, obs, self.false_alarm_rate):
            return
        if self._another_marker(child, obs):
            return
        shift = float(np.linalg.norm(obs.point_level - before.point_level))
        self.journal.failure(
            "child_moved",
            f"{child} moved {1e3 * shift:.1f} mm while {mover} drove; placed again",
            robot=child,
            shift_m=shift,
        )
        self._place(child, obs)
