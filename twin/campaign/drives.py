"""A robot's drives in the campaign, through :mod:`twin.hal`: along a leg's moves and past
the robots that stand, a child's drives off the route to a stop, long drives tracked by
the standing parent, and a drive that ended against something measured where it stopped.

Every drive is counted against the campaign's bound (:class:`Drives`, a part of
:class:`twin.campaign.travel.Travel`, which provides the measurements).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from twin.campaign.aborted import NO_PROGRESS, CampaignAborted, NoProgress
from twin.campaign.journal import Journal
from twin.campaign.plan.clearance import CHILD_BODY, PARENT_BODY, path_clear
from twin.campaign.plan.occlusion import unhidden_yaw
from twin.campaign.plan.ways import ROBOT_MARGIN, WAY_CLEARANCE, robots_clear, way_to
from twin.campaign.strategy import Move
from twin.hal.devices import MobileBase
from twin.hal.readings import DriveResult, DriveStatus
from twin.hal.rig import Rig
from twin.instruments.marker import MarkerAssembly
from twin.localization.observation import ChildObservation
from twin.localization.planar import world2level
from twin.localization.pose import ParentPose
from twin.localization.sequence import CpsSequence
from twin.scenario.schema import Space

ROUTE_TOLERANCE = 0.5
"""A robot farther than this from the route (m) returns to it before following it."""

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
parent (m) may have pushed the parent (:meth:`Drives.check_station`)."""

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


def _near_robot(
    xy: NDArray[np.float64], robots: NDArray[np.float64], keep: NDArray[np.float64]
) -> bool:
    """Whether (2,) ``xy`` lies nearer a standing robot ((K, 2) centres, m) than the
    distance ``keep`` (K,) a child's drive keeps from it."""
    gap = np.linalg.norm(robots - np.asarray(xy, dtype=float).reshape(2), axis=1)
    return bool((gap < keep).any())


class Drives:
    """The robots' drives, for :class:`twin.campaign.travel.Travel` (which provides the
    measurements of a child and the correction of its odometry)."""

    rig: Rig
    cps: CpsSequence
    journal: Journal
    space: Space
    marker: MarkerAssembly
    children: list[str]
    max_drives: int | None
    drives: int

    def measure(self, child: str, parent: ParentPose | None = None) -> ChildObservation | None:
        raise NotImplementedError

    def _correct_child_pose(self, child: str, obs: ChildObservation, parent: ParentPose) -> None:
        raise NotImplementedError

    def child_pose(self, child: str) -> NDArray[np.float64]:
        """(3,) the child's own pose estimate, W."""
        return self.rig.children[child].odometry().pose

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
