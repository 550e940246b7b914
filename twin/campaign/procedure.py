"""The paper's calibration campaign (Section II.B and IV), written against ``twin.hal``.

1. The parent's first station defines W. From there the child takes the reference data
   sets (``campaign.reference_points`` LED points each) for the cameras whose view the
   parent sees (the paper's cameras 1 and 2).
2. The group travels by CPS along the route: the children move ahead and stop, the parent
   measures them, the parent moves, measures the stationary children and solves its pose.
3. At each calibration station a child visits stops spread over the camera's view
   (:func:`twin.campaign.plan.view_stops`) while the parent measures its corner cubes and
   the camera finds its LEDs; the other child stays. The camera is calibrated (Tsai) as
   soon as its data are complete. Visits follow the scenario's order.

Faults do not stop the run: lost locks are retried, points whose LEDs are not all found
are skipped, a station that cannot be reached or yields too few points is reported. Every
failure is recorded (``/campaign/failure``) with its kind.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from calib.detection.sequence import SwitchingSequence
from calib.io.camera_files import camera_to_dict
from calib.tsai import calibrate_tsai
from twin.campaign.geometry import ROBOT_CLEARANCE, free, path_clear, unhidden_yaw
from twin.campaign.plan import Stop, ViewStop, formation, leg_goals, tour, view_stops
from twin.campaign.records import (
    CALIBRATION,
    DATASET,
    FAILURE,
    PARENT_FIX,
    POINT,
    SKIPPED,
    STAGE,
    CalibrationRecord,
    DataPoint,
    DataSet,
    Failure,
    ParentFix,
    SkippedVisit,
    Stage,
)
from twin.campaign.route import RoutePath
from twin.campaign.shooting import measure_child, moved_between, oriented_on, same_marker
from twin.hal.devices import MobileBase
from twin.hal.recording import Recorder
from twin.hal.rig import Rig
from twin.instruments.errors import InconsistentChildrenError
from twin.instruments.marker_pose import led_positions
from twin.localization.observation import ChildObservation
from twin.localization.pose import ParentPose
from twin.localization.sequence import CpsSequence
from twin.scenario.cross_checks import station_visibility
from twin.scenario.geometry import floor_view
from twin.scenario.schema import Scenario
from twin.timing import timed


@dataclass(frozen=True)
class Progress:
    """What the campaign is doing now, for a progress display.

    Attributes:
        stage: ``reference``, ``travel``, ``station`` or ``done``.
        robot: the robot moving ("" if none). camera: the camera concerned ("" if none).
        points: LED points gathered for the current data set.
        calibrated: cameras calibrated so far. detail: words.
    """

    stage: str
    robot: str = ""
    camera: str = ""
    points: int = 0
    calibrated: int = 0
    detail: str = ""


@dataclass
class CampaignOutcome:
    """What the campaign did (its records are in the recorder).

    Attributes:
        calibrations: every calibration, in order. skipped: visits without one.
        failures: count by kind. travelled: the parent's travel, m.
    """

    calibrations: list[CalibrationRecord] = field(default_factory=list)
    skipped: list[SkippedVisit] = field(default_factory=list)
    failures: Counter = field(default_factory=Counter)
    travelled: float = 0.0


class CampaignAborted(RuntimeError):
    """The group cannot go on (CPS lost both children)."""


ROUTE_TOLERANCE = 0.5
"""A robot farther than this from the route (m) returns to it before following it."""

TURNS_DEG = (30.0, -60.0)
"""How a child turns, one after the other, when the parent cannot measure all its prisms."""

SIDESTEPS = (0.4, -0.8)
"""How the parent steps sideways, one after the other, m, when it cannot fix its pose."""


class Campaign:
    """One run of the calibration campaign on a rig.

    Args:
        rig: the devices (simulated or real); only ``twin.hal`` is used.
        scenario: the plan: the map, the cameras' nominal poses, the route, the visits, the
            campaign's settings.
        recorder: receives the campaign's derived records (the rig records its readings).
        progress: called with a :class:`Progress` at each stage and point.
    """

    def __init__(
        self,
        rig: Rig,
        scenario: Scenario,
        recorder: Recorder,
        progress: Callable[[Progress], None] | None = None,
    ) -> None:
        self.rig = rig
        self.sc = scenario
        self.rec = recorder
        self.progress = progress or (lambda p: None)
        self.cfg = scenario.campaign
        self.marker = scenario.marker.assembly()
        self.floor_z = scenario.space.floor_z
        self.path = RoutePath(scenario.route.waypoints)
        self.children = list(rig.children)
        solver = _solver(rig)
        # With a noise-free instrument, consistency tests have no noise to be tested against.
        self.false_alarm_rate = 1e-4 if solver == "wls" else None
        self.cps = CpsSequence(self.children, solver=solver, false_alarm_rate=self.false_alarm_rate)
        self.sequence = (
            SwitchingSequence.binary(len(self.marker.leds_body))
            if self.cfg.led_sequence == "binary"
            else SwitchingSequence.one_at_a_time(len(self.marker.leds_body))
        )
        self.outcome = CampaignOutcome()
        self.references: dict[str, tuple[NDArray, NDArray]] = {}
        self._placed: dict[str, ChildObservation] = {}  # the measurement that placed each child
        self._fixes = 0
        self._stage = Progress("start")
        self._last_xy = np.zeros(2)
        self._s = self.path.project(scenario.robots.parent.start_xy)

    # -- records ---------------------------------------------------------------------------
    def _now(self) -> float:
        return self.rig.clock.now()

    def _fail(self, kind: str, message: str, robot: str = "", camera: str = "", **details):
        self.outcome.failures[kind] += 1
        f = Failure(self._now(), kind, message, robot, camera, dict(details))
        self.rec.record(FAILURE, f, f.timestamp)

    def _stage_start(self, stage: str, camera: str = "", visit: int = 0, detail: str = ""):
        s = Stage(self._now(), stage, camera, visit, detail)
        self.rec.record(STAGE, s, s.timestamp)
        self._stage = Progress(stage, camera=camera, detail=detail)
        self._tell()

    def _tell(self, **changes) -> None:
        fields = {**self._stage.__dict__, **changes}
        fields["calibrated"] = len(self.outcome.calibrations)
        self._stage = Progress(**fields)
        self.progress(self._stage)

    def _timed_solve(self) -> AbstractContextManager[None]:
        return timed(self.rig.timings, "solving")

    # -- the run ---------------------------------------------------------------------------
    def run(self) -> CampaignOutcome:
        """Run the whole campaign and return what it did."""
        self.rig.total_station.read_inclination()
        self._record_fix()
        self._stage_start("reference")
        for cam in self._reference_cameras():
            self._stage_start("reference", cam, 0, f"reference data set of {cam}")
            pts, pix, _ = self._collect(cam, "reference", 0, self.cfg.reference_points)
            if len(pts):
                self.references[cam] = (pts, pix)
        visits_of: Counter = Counter()
        for visit in self.sc.calibration.visits:
            visits_of[visit.camera] += 1
            n = visits_of[visit.camera]
            station = np.asarray(visit.station, dtype=float)
            self._stage_start("travel", visit.camera, n, f"to the station of {visit.camera}")
            try:
                reached = self._travel(station, math.radians(visit.yaw_deg))
            except CampaignAborted as exc:
                self._fail("campaign_aborted", str(exc))
                self._skip(visit.camera, n, station, "campaign_aborted", str(exc))
                break
            if not reached:
                self._skip(
                    visit.camera, n, station, "station_unreachable", "the parent stopped short"
                )
                continue
            self._stage_start("station", visit.camera, n, f"calibrating {visit.camera}")
            self._calibrate_at(visit.camera, n, station)
        self._stage_start("done")
        self.outcome.travelled = self._travelled
        return self.outcome

    # -- reference sets ----------------------------------------------------------------------
    def _reference_cameras(self) -> list[str]:
        if self.cfg.reference_cameras is not None:
            return list(self.cfg.reference_cameras)
        start = self.sc.robots.parent.start_xy
        need = self.sc.calibration.min_visible_fraction
        return [
            c.name
            for c in self.sc.cameras
            if station_visibility(self.sc, c.name, (start[0], start[1])) >= need
        ]

    # -- parent pose ---------------------------------------------------------------------------
    @property
    def _travelled(self) -> float:
        return self._distance

    def _record_fix(self) -> None:
        pose = self.cps.parent
        if self._fixes == 0:
            self._distance = 0.0
        else:
            self._distance += float(np.linalg.norm(pose.translation[:2] - self._last_xy))
        self._last_xy = pose.translation[:2].copy()
        fix = ParentFix(
            self._now(), self._fixes, pose.yaw, pose.translation, pose.covariance, self._distance
        )
        self.rec.record(PARENT_FIX, fix, fix.timestamp)
        self._fixes += 1

    # -- measuring a child ---------------------------------------------------------------------
    def _child_pose(self, child: str) -> NDArray[np.float64]:
        return self.rig.children[child].odometry().pose

    def _measure(self, child: str, parent: ParentPose | None = None) -> ChildObservation | None:
        parent = parent if parent is not None else self.cps.parent

        def report(kind: str, message: str, details: dict) -> None:
            self._fail(kind, message, robot=child, **details)

        return measure_child(
            self.rig.total_station,
            child,
            parent,
            self._child_pose(child),
            self.marker,
            self.floor_z,
            self.cfg.lock_retries,
            report,
            self.false_alarm_rate,
        )

    def _fix_child_pose(self, child: str, obs: ChildObservation, parent: ParentPose) -> None:
        """Correct the child's own localisation from its measured marker pose."""
        if obs.marker_pose is None:
            return
        r = parent.rotation @ obs.marker_pose.rotation
        origin = parent.level2world(obs.marker_pose.translation)
        self.rig.children[child].set_pose(
            float(origin[0]), float(origin[1]), math.atan2(r[1, 0], r[0, 0])
        )

    def _place_child(self, child: str) -> ChildObservation | None:
        """Measure a child that moved (the parent stands) and place it in the CPS state."""
        obs = self._measure(child)
        if obs is not None:
            self._put(child, obs)
        return obs

    def _put(self, child: str, obs: ChildObservation) -> None:
        """Place a child measured from the standing parent in the CPS state."""
        with self._timed_solve():
            self.cps.children_moved([obs])
        self._fix_child_pose(child, obs, self.cps.parent)
        self._placed[child] = obs

    def _check_stayed(self, child: str, mover: str) -> None:
        """Measure a placed child again after ``mover`` drove (the parent stands), as a
        surveyor checks a backsight; place it anew if it moved.

        A parked robot can be pushed, or roll off a ledge; if it moved unnoticed, the
        parent's next fix would find the two children inconsistent with no way to tell
        which one moved.
        """
        before = self._placed.get(child)
        if before is None:
            return
        obs = self._measure(child)
        if obs is None or not moved_between(before, obs, self.false_alarm_rate):
            return
        shift = float(np.linalg.norm(obs.point_level - before.point_level))
        self._fail(
            "child_moved",
            f"{child} moved {1e3 * shift:.1f} mm while {mover} drove; placed again",
            robot=child,
            shift_m=shift,
        )
        self._put(child, obs)

    def _place_child_turning(self, child: str) -> ChildObservation | None:
        """:meth:`_place_child`; if a prism stays out of reach, the child turns on the spot
        (its reference point is on its mast, the axis it turns about) and is measured again."""
        obs = self._place_child(child)
        for turn in TURNS_DEG:
            if obs is not None:
                return obs
            pose = self._child_pose(child)
            self._fail("child_turned", f"turning {turn:+.0f} deg to show its prisms", child)
            self.rig.children[child].drive_to(pose[:2], pose[2] + math.radians(turn))
            obs = self._place_child(child)
        return obs

    # -- travel ----------------------------------------------------------------------------------
    def _drive_along(self, base: MobileBase, s_from: float, s_to: float, goal: Stop) -> bool:
        """Drive a base along the route's corners between two arc lengths, then to ``goal``."""
        self._tell(robot=base.name)
        here = base.odometry().pose[:2]
        corners = self.path.vertices_between(s_from, s_to)
        first = corners[0] if corners else goal.xy
        entry = self.path.at(s_from)
        # Off the route (in a camera's view, say) with an obstacle in the way: back onto the
        # route first.
        blocked = not path_clear(self.sc, here, first, 0.3)
        far = np.linalg.norm(here - entry) > ROUTE_TOLERANCE
        if blocked and far and not base.drive_to(entry).reached:
            return False
        waypoints = list(corners)
        last = waypoints[-1] if waypoints else here
        on_route = self.path.at(s_to)
        if (
            not path_clear(self.sc, last, goal.xy, 0.35)
            and np.linalg.norm(on_route - goal.xy) > 0.1
        ):
            waypoints.append(on_route)  # along the route, then sideways to the goal
        for point in waypoints:
            if not base.drive_to(point).reached:
                return False
        return base.drive_to(goal.xy, goal.yaw).reached

    def _travel(self, station: NDArray[np.float64], yaw: float) -> bool:
        """CPS legs from the parent's place to ``station``; False if it was not reached."""
        parent_xy = self.cps.parent.translation[:2]
        s_now = self.path.project(parent_xy, near=self._s)
        s_goal = self.path.project(station)
        if np.linalg.norm(station - parent_xy) < 0.05:
            return True
        direction = 1.0 if s_goal >= s_now else -1.0
        goals = leg_goals(self.path, s_now, s_goal, self.cfg.formation.step)
        while goals:
            s_next = goals[0]
            last = len(goals) == 1
            next_xy = station if last else self.path.at(s_next)
            z = float(self.cps.parent.translation[2])
            waiting = self._child_pose(self._children_in_order(direction)[1])[:2]
            with timed(self.rig.timings, "planning"):
                stops = formation(
                    self.sc,
                    self.path,
                    s_next,
                    parent_xy,
                    next_xy,
                    direction,
                    self.cfg.formation,
                    z,
                    waiting_xy=waiting,
                )
            if stops is None:
                # No room for the children ahead: a shorter leg (down to a quarter step).
                if abs(s_next - s_now) > 0.3 * self.cfg.formation.step:
                    goals.insert(0, 0.5 * (s_now + s_next))
                    continue
                self._fail("no_formation", f"no place for the children ahead of s = {s_next:.1f} m")
                raise CampaignAborted(f"no formation for the leg to s = {s_next:.1f} m")
            goals.pop(0)
            self._move_children(stops, direction)
            heading = yaw if last else self.path.heading(s_next) + (0 if direction > 0 else math.pi)
            reached = self._drive_along(self.rig.parent, s_now, s_next, Stop(next_xy, heading))
            self._fix_parent()
            parent_xy = self.cps.parent.translation[:2]
            s_now = self._s = self.path.project(parent_xy, near=s_next)
            if not reached:
                self._fail("parent_blocked", "the parent stopped short of its goal", robot="parent")
                if last:
                    return False
        return True

    def _children_in_order(self, direction: float) -> list[str]:
        """The two children, the one furthest ahead along the route first (it moves first)."""
        s = {c: self.path.project(self._child_pose(c)[:2], near=self._s) for c in self.children[:2]}
        return sorted(s, key=lambda c: direction * s[c], reverse=True)

    def _move_children(self, stops: list[Stop], direction: float) -> None:
        """Send the children to their formation stops (the far one first) and measure them;
        then check that the ones placed first stayed while the others drove."""
        order = self._children_in_order(direction)
        s = {c: self.path.project(self._child_pose(c)[:2], near=self._s) for c in order}
        for child, stop in zip(order, stops, strict=True):
            s_stop = self.path.project(stop.xy, near=self._s)
            drive = self._drive_along(self.rig.children[child], s[child], s_stop, stop)
            if not drive:
                self._fail("child_blocked", "the child stopped short of its stop", robot=child)
            if self._place_child_turning(child) is None:
                raise CampaignAborted(f"the parent cannot measure {child}")
        for child in order[:-1]:
            self._check_stayed(child, order[-1])

    def _fix_parent(self) -> None:
        """The parent moved: measure the stationary children, solve its pose."""
        z = float(self.cps.parent.translation[2])
        for attempt in range(2 + len(SIDESTEPS)):
            if attempt >= 2:
                # A child's prism stays hidden from here: CPS solves the parent's pose
                # wherever it stands, so it steps aside and measures again.
                step = SIDESTEPS[attempt - 2]
                odo = self.rig.parent.odometry()
                side = np.array([-math.sin(odo.yaw), math.cos(odo.yaw)]) * step
                target = odo.pose[:2] + side
                if not free(self.sc, target[None], ROBOT_CLEARANCE)[0]:
                    continue
                self._fail("parent_stepped_aside", f"{step:+.1f} m to see the children", "parent")
                self.rig.parent.drive_to(target, odo.yaw)
            odo = self.rig.parent.odometry()
            guess = ParentPose(odo.yaw, np.array([odo.x, odo.y, z]))
            self.rig.total_station.read_inclination()
            # A retry starts from the other child: the first one measured orients the aim
            # at the next, and a wrong first one must not spoil every attempt.
            order = self.children if attempt % 2 == 0 else self.children[::-1]
            obs: list[ChildObservation] = []
            for child in order:
                o = self._measure(child, guess)
                if o is None:
                    continue
                seen = next((p for p in obs if same_marker(p.point_level, o.point_level)), None)
                if seen is not None:
                    self._fail(
                        "wrong_child",
                        f"{child}'s shots found {seen.child}'s marker again",
                        robot=child,
                        attempt=attempt,
                    )
                    continue
                obs.append(o)
                guess = oriented_on(guess, self.cps.child_position(child)[0], o.point_level)
            if len(obs) < 2:
                self._fail("parent_fix_failed", f"measured {len(obs)} children", robot="parent")
                continue
            try:
                with self._timed_solve():
                    self.cps.parent_moved(obs)
            except InconsistentChildrenError as exc:
                self._fail("inconsistent_children", str(exc), robot="parent", attempt=attempt)
                continue
            except ValueError as exc:  # geometry that cannot fix the yaw (children in line)
                self._fail("parent_fix_failed", str(exc), robot="parent", attempt=attempt)
                continue
            pose = self.cps.parent
            self.rig.parent.set_pose(
                float(pose.translation[0]), float(pose.translation[1]), pose.yaw
            )
            self._record_fix()
            return
        raise CampaignAborted("the parent could not fix its pose from the children")

    # -- data -------------------------------------------------------------------------------------
    def _choose_child(self, camera: str) -> str:
        cam = self.sc.camera(camera).tsai()
        ground = floor_view(cam, self.floor_z, max_range=40.0, grid=12)
        centre = ground[:, :2].mean(axis=0) if len(ground) else cam.position[:2]
        return min(
            self.children, key=lambda c: float(np.linalg.norm(self._child_pose(c)[:2] - centre))
        )

    def _collect(
        self, camera: str, dataset: str, visit: int, target: int
    ) -> tuple[NDArray, NDArray, list]:
        """LED points of ``camera``: (N, 3) in W, (N, 2) pixels, and the data points."""
        child = self._choose_child(camera)
        anchor = next(c for c in self.children if c != child)
        parent = self.cps.parent
        with timed(self.rig.timings, "planning"):
            candidates = view_stops(
                self.sc,
                self.sc.camera(camera).tsai(),
                parent.translation[:2],
                float(parent.translation[2]),
                self._child_pose(anchor)[:2],
            )
        n_leds = len(self.marker.leds_body)
        need = math.ceil(target / n_leds)
        if not candidates:
            self._fail("no_view_stops", "no place in the view for the child", child, camera)
            return np.zeros((0, 3)), np.zeros((0, 2)), []
        plan: list[ViewStop] = tour(candidates[:need], self._child_pose(child)[:2])
        spares = candidates[need:]
        sensor = self.rig.led_sensors[camera]
        base = self.rig.children[child]
        pts: list[NDArray] = []
        pix: list[NDArray] = []
        points: list[DataPoint] = []
        while plan and len(pts) < target:
            stop = plan.pop(0).stop
            self._tell(robot=child, camera=camera, points=len(pts))
            # Turn the child where its own mast, arms or prisms would hide a prism.
            with timed(self.rig.timings, "planning"):
                yaw = unhidden_yaw(
                    stop.xy,
                    stop.yaw,
                    self.marker.cubes_body,
                    parent.translation,
                    self.floor_z,
                    50.0,
                )
            if yaw is None:
                self._fail("prisms_hidden", "every heading hides a prism", child, camera)
                plan += spares[:1]
                spares = spares[1:]
                continue
            result = base.drive_to(stop.xy, yaw)
            if not result.reached:
                self._fail(
                    "point_unreachable", result.message or result.status.value, child, camera
                )
                plan += spares[:1]
                spares = spares[1:]
                continue
            obs = self._place_child_turning(child)
            if obs is None:
                self._fail("point_skipped", "the child's prisms were not measured", child, camera)
                plan += spares[:1]
                spares = spares[1:]
                continue
            seen = sensor.observe(child, self.sequence)
            if not seen.complete:
                kinds = sorted({f for f in seen.failures if f is not None})
                for kind in kinds:
                    self._fail(f"led_{kind}", f"LEDs {kind}", child, camera)
                self._fail(
                    "point_skipped", "not all LEDs found: " + ", ".join(kinds), child, camera
                )
                plan += spares[:1]
                spares = spares[1:]
                continue
            assert obs.marker_pose is not None
            leds_level, _ = led_positions(obs.marker_pose, self.marker)
            leds_w = self.cps.parent.level2world(leds_level)
            point = DataPoint(
                self._now(),
                dataset,
                camera,
                visit,
                child,
                leds_w,
                seen.pixels,
                self.cps.parent.level2world(obs.point_level)[:2],
            )
            self.rec.record(POINT, point, point.timestamp)
            points.append(point)
            pts += list(leds_w)
            pix += list(seen.pixels)
        self._tell(points=len(pts))
        n = min(target, len(pts))
        done = DataSet(self._now(), dataset, camera, visit, n)
        self.rec.record(DATASET, done, done.timestamp)
        return np.array(pts[:n]).reshape(-1, 3), np.array(pix[:n]).reshape(-1, 2), points

    def _skip(self, camera: str, visit: int, station: NDArray, reason: str, message: str) -> None:
        s = SkippedVisit(self._now(), camera, visit, station, reason, message)
        self.outcome.skipped.append(s)
        self.rec.record(SKIPPED, s, s.timestamp)

    def _calibrate_at(self, camera: str, visit: int, station: NDArray[np.float64]) -> None:
        pts, pix, _ = self._collect(camera, "visit", visit, self.cfg.station_points)
        if len(pts) < self.cfg.min_points:
            self._skip(
                camera,
                visit,
                station,
                "too_few_points",
                f"{len(pts)} points, {self.cfg.min_points} needed",
            )
            return
        size = self.rig.led_sensors[camera].image_size
        try:
            with self._timed_solve():
                result = calibrate_tsai(pts, pix, size)
        except ValueError as exc:
            self._fail("calibration_failed", str(exc), camera=camera)
            self._skip(camera, visit, station, "calibration_failed", str(exc))
            return
        record = CalibrationRecord(
            timestamp=self._now(),
            camera=camera,
            visit=visit,
            station=station,
            distance_travelled=self._travelled,
            points=len(pts),
            parameters=result.parameters,
            std=result.std_by_name,
            camera_model=camera_to_dict(result.camera),
            sigma_px=result.sigma_px,
        )
        self.outcome.calibrations.append(record)
        self.rec.record(CALIBRATION, record, record.timestamp)
        self._tell()


def _solver(rig: Rig) -> str:
    """WLS weighs the children by their covariance; an instrument with a noise-free axis
    gives singular covariances, and then the closed form (eq. 2), which needs none."""
    spec, tilt = rig.total_station.spec, rig.total_station.inclinometer
    sigmas = (spec.distance_sigma(1.0), spec.angle_sigma, 1.0 if tilt is None else tilt.sigma)
    return "wls" if min(sigmas) > 0 and len(rig.children) > 1 else "closed_form"
