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
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from twin.campaign.aborted import CampaignAborted
from twin.campaign.control_points import ControlPoints
from twin.campaign.journal import Journal, RobotJournal
from twin.campaign.parent_fix import FIX_ATTEMPTS, SIDESTEPS
from twin.campaign.plan.clearance import (
    CHILD_BODY,
    PARENT_BODY,
    path_clear,
)
from twin.campaign.plan.occlusion import unhidden_yaw
from twin.campaign.plan.ways import ROBOT_MARGIN, WAY_CLEARANCE, robots_clear, way_to
from twin.campaign.recovery import LegRecovery
from twin.campaign.shooting import measure_child, moved_between, same_marker
from twin.campaign.strategy import Leg, Move
from twin.hal.devices import MobileBase
from twin.hal.readings import DriveResult, DriveStatus
from twin.hal.rig import Rig
from twin.instruments.marker import MarkerAssembly
from twin.localization.observation import ChildObservation
from twin.localization.planar import world2level
from twin.localization.pose import ParentPose
from twin.localization.sequence import CpsSequence
from twin.scenario.schema import Space
from twin.timing import timed

ROUTE_TOLERANCE = 0.5
"""A robot farther than this from the route (m) returns to it before following it."""

TURNS_DEG = (30.0, -60.0)
"""How a child turns, one after the other, when the parent cannot measure all its prisms."""

LONG_DRIVE_M = 30.0
"""A child's straight drive longer than this, m, is tracked by the standing parent. A
robot's heading is known to about a degree after it stops and turns, and its wheel
odometry carries that error along the drive (0.5 m of side error after 30 m): a child
sent back 100 m and more (from the far end of a reference data set, say) would stop out
of the instrument's aim, or behind a corner it was planned clear of."""

TRACK_STEP_M = 10.0
"""A tracked drive stops about every this many metres, m, to be measured, and the child's
odometry is corrected from its marker's measured pose."""

BUMP_REACH = 0.3
"""A child that stopped against something within the two robots' radii and this of the
parent (m) may have pushed the parent (:meth:`Travel.check_station`)."""

STATION_GATE_M = 0.015
"""How far a standing child may be measured from where the parent's CPS state expects it
before the station counts as moved, m. The parent measured it from this station (at its
fix, or placing it): the two agree to the shots' noise, a few millimetres; a push of the
parent that turns it 10 mrad moves a child 3 m away by 30 mm."""

DETOUR_FACTOR = 2.0
DETOUR_M = 4.0
"""A child's way to a stop off the route with more than one corner is not driven where it
is longer than :data:`DETOUR_FACTOR` times the straight line plus :data:`DETOUR_M`, m.
Both ends are in the standing parent's sight, and a way that long goes round a wall out
of it: the child drives it on its odometry alone, its heading's error carried along, and
may stop off its estimate by more than the way keeps from the walls (against a wall, it
is turned, and the parent finds it nowhere near where it believes it is). A way of one
corner beside the straight line (:data:`twin.campaign.plan.ways.CORNER_OFFSETS`) is
driven whatever its length."""

NO_PROGRESS = "no_progress"
"""The failure of a loop of the campaign that reached its bound (:mod:`twin.campaign.bounds`)."""


class NoProgress(CampaignAborted):
    """A loop of the campaign reached its bound (:mod:`twin.campaign.bounds`): the campaign
    cannot progress. Made and recorded by :meth:`Travel.no_progress`.

    Attributes:
        stage: the campaign's stage (``reference``, ``travel``, ``station``, ``return``).
        what: what was counted (legs of a travel, travels, stops of a data set, drives).
        position: (2,) where the parent stands (its CPS estimate), m in W.
        count: how many were taken. bound: the most allowed.
    """

    def __init__(
        self, stage: str, what: str, position: NDArray[np.float64], count: int, bound: int
    ) -> None:
        self.stage, self.what, self.count, self.bound = stage, what, count, bound
        self.position = np.asarray(position, dtype=float).reshape(2).copy()
        x, y = self.position
        super().__init__(
            f"no progress in the {stage} stage, the parent at ({x:.2f}, {y:.2f}) m: {count} "
            f"{what}, the most the scenario allows (campaign.progress_slack)"
        )


__all__ = ["FIX_ATTEMPTS", "SIDESTEPS", "CampaignAborted", "NoProgress", "Travel"]


def _near_robot(
    xy: NDArray[np.float64], robots: NDArray[np.float64], keep: NDArray[np.float64]
) -> bool:
    """Whether (2,) ``xy`` lies nearer a standing robot ((K, 2) centres, m) than the
    distance ``keep`` (K,) a child's drive keeps from it."""
    gap = np.linalg.norm(robots - np.asarray(xy, dtype=float).reshape(2), axis=1)
    return bool((gap < keep).any())


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

    def drive_along(self, base: MobileBase, move: Move) -> bool:
        """Drive a base along the move's corners, then to its stop; False if a drive was
        not completed."""
        self.journal.show(robot=base.name)
        here = base.odometry().pose[:2]
        first = move.corners[0] if move.corners else move.stop.xy
        # Off the route (in a camera's view, say) with an obstacle in the way: back onto the
        # route first.
        blocked = not path_clear(self.space, here, first, 0.3)
        far = np.linalg.norm(here - move.entry) > ROUTE_TOLERANCE
        if blocked and far and not self._drive_round(base, move.entry).reached:
            return False
        waypoints = list(move.corners)
        last = waypoints[-1] if waypoints else here
        if (
            not path_clear(self.space, last, move.stop.xy, 0.35)
            and np.linalg.norm(move.on_route - move.stop.xy) > 0.1
        ):
            waypoints.append(move.on_route)  # along the route, then sideways to the stop
        # A corner of the route where a robot stands (a leg that starts at a turn, the
        # parent on it) is passed by: driven to, the child would push that robot, and be
        # turned off its own estimate. The drive after it goes round, clear of the map.
        standing = self.standing_robots(base.name) if base.name in self.rig.children else None
        passed = False
        for point in waypoints:
            if standing is not None and _near_robot(point, *standing):
                passed = True
                continue
            if not self._drive_round(base, point, keep_map=passed).reached:
                return False
            passed = False
        return self._drive_round(base, move.stop.xy, move.stop.yaw, keep_map=passed).reached

    def _drive_round(
        self,
        base: MobileBase,
        goal_xy: NDArray[np.float64],
        goal_yaw: float | None = None,
        keep_map: bool = False,
    ) -> DriveResult:
        """:meth:`_drive`; a child's whose straight drive passes a standing robot closer
        than :meth:`standing_robots` keeps goes first through the corner of a way round it
        (:func:`twin.campaign.plan.ways.way_to`), where the map leaves one (else straight
        on, as planned). A route's corner can be where the parent stands (a leg that starts
        at a turn), and a child that left the route for a camera's data comes back to it
        past the parent. ``keep_map``: a drive that cuts a corner of the route (one passed
        by) goes round where its straight line comes nearer the map than a way keeps."""
        if base.name in self.rig.children:
            here = base.odometry().pose[:2]
            robots, keep = self.standing_robots(base.name)
            cuts = keep_map and not path_clear(self.space, here, goal_xy, WAY_CLEARANCE)
            if cuts or not robots_clear(here, goal_xy, robots, keep):
                for corner in way_to(self.space, here, goal_xy, robots, keep) or []:
                    result = self._drive(base, corner)
                    if not result.reached:
                        return result
        return self._drive(base, goal_xy, goal_yaw)

    def _drive(
        self, base: MobileBase, goal_xy: NDArray[np.float64], goal_yaw: float | None = None
    ) -> DriveResult:
        """One straight drive; a child's longer than :data:`LONG_DRIVE_M` in pieces of about
        :data:`TRACK_STEP_M`, measured after each. How it ended (a piece that did not get
        there ends it)."""
        if base.name in self.rig.children:
            here = base.odometry().pose[:2]
            length = float(np.linalg.norm(goal_xy - here))
            if length > LONG_DRIVE_M:
                pieces = math.ceil(length / TRACK_STEP_M)
                heading = math.atan2(*(goal_xy - here)[::-1])
                for k in range(1, pieces):
                    point = here + (goal_xy - here) * (k / pieces)
                    result = self._go(base, point, self._showing(point, heading))
                    if not result.reached:
                        return result
                    self._track(base.name)
        return self._go(base, goal_xy, goal_yaw)

    def _go(
        self, base: MobileBase, goal_xy: NDArray[np.float64], goal_yaw: float | None = None
    ) -> DriveResult:
        """Every drive of a robot, counted.

        Raises:
            NoProgress: the campaign's robots have driven ``max_drives`` times already.
        """
        if self.max_drives is not None and self.drives >= self.max_drives:
            raise self.no_progress("drives of the robots", self.drives, self.max_drives)
        self.drives += 1
        return base.drive_to(goal_xy, goal_yaw)

    def no_progress(
        self, what: str, count: int, bound: int, robot: str = "", camera: str = ""
    ) -> NoProgress:
        """A loop reached its bound: the failure ``no_progress`` recorded, naming the stage,
        where the parent stands, ``what`` was counted, the ``count`` and the ``bound``. The
        exception, for a caller that cannot go on to raise."""
        stuck = NoProgress(
            self.journal.current.stage, what, self.cps.parent.translation[:2], count, bound
        )
        x, y = stuck.position
        self.journal.failure(
            NO_PROGRESS,
            str(stuck),
            robot,
            camera,
            stage=stuck.stage,
            what=what,
            x=float(x),
            y=float(y),
            count=count,
            bound=bound,
        )
        return stuck

    # -- a child's drives off the route ----------------------------------------------------------
    def standing_robots(self, mover: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(K, 2) where the robots other than the child ``mover`` stand, m (the parent's
        CPS estimate, the other children's own estimates), and (K,) the distance a drive
        of ``mover`` keeps from each, m (the two radii and :data:`ROBOT_MARGIN`)."""
        others = [c for c in self.children if c != mover]
        centres = [self.cps.parent.translation[:2]] + [self.child_pose(c)[:2] for c in others]
        keep = [PARENT_BODY + CHILD_BODY + ROBOT_MARGIN]
        keep += [2 * CHILD_BODY + ROBOT_MARGIN] * len(others)
        return np.array(centres, dtype=float).reshape(-1, 2), np.array(keep)

    def drive_clear(self, child: str, goal_xy: NDArray[np.float64], goal_yaw: float) -> str:
        """Drive a child to a stop off the route by a way clear of the standing robots and
        the map (:func:`twin.campaign.plan.ways.way_to`); "" when it got there, else why
        not (no way, or one round a wall too long to drive blind: :data:`DETOUR_FACTOR`).

        A drive that ended against something (a collision, a timeout) may have left the
        child off its own estimate: it is measured where it stopped and its odometry
        corrected (:meth:`relocate`), so that its next drive starts from where it is.
        """
        base = self.rig.children[child]
        robots, keep = self.standing_robots(child)
        here = self.child_pose(child)[:2]
        way = way_to(self.space, here, goal_xy, robots, keep)
        if way is None:
            return "no way clear of the robots standing and the map"
        straight = float(np.linalg.norm(goal_xy - here))
        length = float(np.sum(np.linalg.norm(np.diff([here, *way, goal_xy], axis=0), axis=1)))
        if len(way) > 1 and length > DETOUR_FACTOR * straight + DETOUR_M:
            return f"the way round is {length:.1f} m long, for a stop {straight:.1f} m away"
        for corner, yaw in [*((c, None) for c in way), (goal_xy, goal_yaw)]:
            result = self._drive(base, corner, yaw)
            if not result.reached:
                if result.status in (DriveStatus.COLLISION, DriveStatus.TIMEOUT):
                    seen = self.relocate(child)
                    if result.status is DriveStatus.COLLISION:
                        self.check_station(child, seen)
                return result.message or result.status.value
        return ""

    def check_station(self, child: str, seen: ChildObservation | None) -> None:
        """A child stopped against something (``seen``: where the parent measured it then,
        or None): if that was beside the standing parent, it may have pushed the parent off
        its station, and every point measured after it would be in another frame. The
        parent measures the other children and compares each with where its CPS state
        expects it; one farther than :data:`STATION_GATE_M` means the station moved (or
        that child was pushed too: from one reference the two cannot be told apart, and
        either way the points measured from here can no longer be trusted).

        Raises:
            CampaignAborted: the station moved (the parent cannot fix its pose again from
                children standing where it knows them).
        """
        parent = self.cps.parent
        if seen is not None:
            reach = float(np.linalg.norm(seen.point_level[:2]))
        else:
            reach = float(np.linalg.norm(self.child_pose(child)[:2] - parent.translation[:2]))
        if reach > PARENT_BODY + CHILD_BODY + BUMP_REACH:
            return
        for other in self.children:
            if other == child:
                continue
            obs = self.measure(other)
            if obs is None:
                continue
            expected = world2level(
                self.cps.child_position(other)[0], parent.yaw, parent.translation
            )
            off = float(np.linalg.norm(obs.point_level - expected))
            if off > STATION_GATE_M:
                message = (
                    f"{child} stopped against the parent, and {other} is now {1e3 * off:.0f} mm "
                    "off where the parent expects it: the station moved (or that child did)"
                )
                self.journal.failure("station_moved", message, robot=self.rig.parent.name)
                raise CampaignAborted(message)
            self.journal.event("station_checked", f"{other} where expected after a bump", other)
            return

    def relocate(
        self,
        child: str,
        event: str = "child_relocated",
        message: str = "measured where its drive ended",
    ) -> ChildObservation | None:
        """Measure a child where a drive left it (the parent stands) and correct its
        odometry, recording ``event``; a child the parent cannot see stays as it is. Its
        observation, or None."""
        obs = self.measure(child)
        if obs is None:
            return None
        self.journal.event(event, message, child)
        self._correct_child_pose(child, obs, self.cps.parent)
        return obs

    def _showing(self, xy: NDArray[np.float64], heading: float) -> float:
        """The heading nearest ``heading`` (rad) at which a child at ``xy`` shows all its
        prisms to the standing parent (``heading`` itself where none does)."""
        eye = self.cps.parent.translation
        turned = unhidden_yaw(xy, heading, self.marker.cubes_body, eye[None], self.space.floor_z)
        return heading if turned is None else turned

    def _track(self, child: str) -> None:
        """Measure a child on its way (the parent stands) and correct its odometry; a child
        the parent cannot see drives on as it is."""
        self.relocate(child, "child_tracked", "measured on a long drive")

    # -- measuring and placing children -------------------------------------------------------
    def child_pose(self, child: str) -> NDArray[np.float64]:
        """(3,) the child's own pose estimate, W."""
        return self.rig.children[child].odometry().pose

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
        if obs is None or not moved_between(before, obs, self.false_alarm_rate):
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
