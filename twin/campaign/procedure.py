"""The paper's calibration campaign (Section II.B and IV), written against ``twin.hal``.

The procedure orders the stages and holds no decision of its own: it asks its strategy
(:mod:`twin.campaign.strategy`) and executes the answers.

1. The parent's first station defines W. From there the child takes the reference data
   sets of the cameras the strategy names.
2. The group travels by CPS to each visit's station, leg by leg (:mod:`.travel`): the
   children move ahead and stop, the parent measures them, the parent moves, measures the
   stationary children and solves its pose.
3. At the station a child visits the stops the strategy plans for the camera while the
   parent measures its corner cubes and the camera finds its LEDs; the other child stays.
   The camera is calibrated (Tsai) as soon as its data are complete (:mod:`.collection`).

Faults do not stop the run: lost locks are retried, points whose LEDs are not all found
are skipped, a station that cannot be reached or yields too few points is reported. Every
failure is recorded (``/campaign/failure``) with its kind; the campaign's own recoveries
(a child turning, the parent stepping aside, a prism aimed at again) are events
(``/campaign/event``). A leg that fails all the same (a child the parent cannot measure,
a parent that cannot fix its pose) is backed off from and planned again, shorter
(:mod:`.recovery`, events ``child_backed_off`` and ``parent_backed_off``).
Every loop ends within a bound computed from the scenario (:mod:`.bounds`): a travel whose
legs, a campaign whose travels, or robots whose drives reach theirs end the campaign with
the failure ``no_progress``, which names the stage, where the parent stands and the count.

:meth:`Campaign.steps` is the procedure as a generator of questions (a
:class:`twin.campaign.strategy.Question` for each decision, answered by ``send``):
:meth:`Campaign.run` answers them with the strategy; an environment can answer them
itself, one decision at a time.
"""

from __future__ import annotations

from collections.abc import Callable, Generator
from typing import Any

import numpy as np
from numpy.typing import NDArray

from calib.detection.sequence import SwitchingSequence
from twin.campaign.bounds import CampaignBounds, campaign_bounds
from twin.campaign.collection import DataCollection
from twin.campaign.control_points import ControlPoints
from twin.campaign.journal import CampaignOutcome, Journal, Progress
from twin.campaign.records import CalibrationRecord
from twin.campaign.recovery import LegRecovered
from twin.campaign.strategies import strategy_named
from twin.campaign.strategy import (
    CampaignView,
    DataStops,
    Leg,
    NextLeg,
    NextVisit,
    NoLeg,
    Question,
    ReferenceCameras,
    Return,
    StopPlan,
    Strategy,
    Visit,
)
from twin.campaign.travel import CampaignAborted, NoProgress, Travel
from twin.hal.errors import DeviceLostError
from twin.hal.recording import Recorder
from twin.hal.rig import Rig
from twin.hal.structure import check_rig_structure
from twin.instruments.errors import TiltOutOfRangeError
from twin.instruments.total_station import TotalStationSpec
from twin.localization.pose import ParentPose
from twin.localization.sequence import CpsSequence
from twin.scenario.schema import Scenario
from twin.timing import timed

__all__ = ["Campaign", "CampaignAborted", "CampaignOutcome", "NoProgress", "Progress"]


class _RigView(CampaignView):
    """What the campaign knows, from its CPS state, its journal and the rig's interface."""

    def __init__(self, scenario: Scenario, rig: Rig, cps: CpsSequence, journal: Journal) -> None:
        self._scenario, self._rig, self._cps, self._journal = scenario, rig, cps, journal
        self._children = tuple(rig.children)
        self._led_count = next(iter(rig.leds.values())).count

    @property
    def scenario(self) -> Scenario:
        return self._scenario

    @property
    def instrument(self) -> TotalStationSpec:
        return self._rig.total_station.spec

    @property
    def parent_name(self) -> str:
        return self._rig.parent.name

    @property
    def children(self) -> tuple[str, ...]:
        return self._children

    @property
    def led_count(self) -> int:
        return self._led_count

    @property
    def parent(self) -> ParentPose:
        return self._cps.parent

    def child_position(self, child: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return self._cps.child_position(child)

    def robot_pose(self, robot: str) -> NDArray[np.float64]:
        return self._rig.base(robot).odometry().pose

    @property
    def calibrations(self) -> tuple[CalibrationRecord, ...]:
        return tuple(self._journal.outcome.calibrations)


class Campaign:
    """One run of the calibration campaign on a rig.

    Args:
        rig: the devices (simulated or real); only ``twin.hal`` is used.
        scenario: the plan: the map, the cameras' nominal poses, the route, the visits, the
            campaign's settings.
        recorder: receives the campaign's derived records (the rig records its readings).
        progress: called with a :class:`Progress` at each stage and point.
        strategy: the campaign's decisions (default: the one ``campaign.strategy`` names).

    Attributes:
        bounds: the most each of its loops may take (:func:`twin.campaign.bounds.
            campaign_bounds` of the scenario); a loop that reaches its bound ends with the
            failure ``no_progress``.

    Raises:
        twin.hal.RigCheckError: the rig lacks a device the scenario needs (an LED sensor
            for one of its cameras, say).
    """

    def __init__(
        self,
        rig: Rig,
        scenario: Scenario,
        recorder: Recorder,
        progress: Callable[[Progress], None] | None = None,
        strategy: Strategy | None = None,
    ) -> None:
        check_rig_structure(rig, [c.name for c in scenario.cameras])
        self.rig = rig
        self.scenario = scenario
        self.settings = scenario.campaign
        self.strategy = strategy if strategy is not None else strategy_named(self.settings.strategy)
        self.bounds: CampaignBounds = campaign_bounds(scenario)
        self.journal = Journal(recorder, rig.clock, progress)
        solver = _solver(rig)
        # With a noise-free instrument, consistency tests have no noise to be tested against.
        self.false_alarm_rate = 1e-4 if solver == "wls" else None
        self.cps = CpsSequence(
            list(rig.children),
            solver=solver,
            false_alarm_rate=self.false_alarm_rate,
            child_creep=self.settings.child_creep_m,
        )
        marker = scenario.marker.assembly()
        self.travel = Travel(
            rig,
            self.cps,
            self.journal,
            scenario.space,
            marker,
            self.settings.lock_retries,
            self.false_alarm_rate,
            self.bounds.drives,
            self.bounds.recoveries,
        )
        sequence = (
            SwitchingSequence.binary(len(marker.leds_body))
            if self.settings.led_sequence == "binary"
            else SwitchingSequence.one_at_a_time(len(marker.leds_body))
        )
        if scenario.control_points:
            self.travel.control_points = ControlPoints(
                rig.total_station, self.journal, scenario.control_points, self.settings.lock_retries
            )
        self.collection = DataCollection(rig, self.travel, self.journal, self.settings, sequence)
        self.view: CampaignView = _RigView(scenario, rig, self.cps, self.journal)
        self.references: dict[str, tuple[NDArray, NDArray]] = {}

    @property
    def outcome(self) -> CampaignOutcome:
        """What the campaign did so far."""
        return self.journal.outcome

    # -- the run -------------------------------------------------------------------------------
    def run(self) -> CampaignOutcome:
        """Run the whole campaign, its strategy answering every question, and return what
        it did."""
        self.strategy.start(self.view)
        steps = self.steps()
        answer: Any = None
        while True:
            try:
                question = steps.send(answer)
            except StopIteration as end:
                return end.value
            with timed(self.rig.timings, "planning"):
                answer = question.ask(self.strategy, self.view)

    def steps(self) -> Generator[Question, Any, CampaignOutcome]:
        """The campaign as a generator: it yields each :class:`Question` and goes on with
        the answer sent back (the first ``send`` is None), and returns the outcome.

        Whoever answers starts its strategy first (:meth:`Strategy.start
        <twin.campaign.strategy.Strategy.start>` with :attr:`view`), as :meth:`run` does.

        A device that is lost (:class:`twin.hal.errors.DeviceLostError`: a real device
        stopped answering, or its link closed) ends the campaign: the failure is recorded
        (``device_lost``) and what was calibrated before is kept.
        """
        try:
            return (yield from self._steps())
        except DeviceLostError as exc:
            self.journal.failure("device_lost", str(exc), device=exc.device, **exc.details)
            self.journal.failure("campaign_aborted", f"a device is lost: {exc}")
            self.journal.stage("done")
            self.outcome.travelled = self.journal.travelled
            return self.outcome

    def _steps(self) -> Generator[Question, Any, CampaignOutcome]:
        try:
            self.rig.total_station.read_inclination()
        except TiltOutOfRangeError as exc:
            # The first station defines W level: on a slope beyond the sensor's range the
            # instrument cannot level a single shot.
            self.journal.failure(exc.reason.value, str(exc), self.rig.parent.name)
            self.journal.failure("campaign_aborted", "the first station leans too far")
            self.journal.stage("done")
            return self.outcome
        self.journal.parent_fix(self.cps.parent)
        if self.travel.control_points is not None:
            self.travel.control_points.sight(self.cps.parent, self.rig.parent.name)
        self.journal.stage("reference")
        cameras = yield ReferenceCameras()
        for camera in cameras:
            self.journal.stage("reference", camera, 0, f"reference data set of {camera}")
            plan = yield DataStops(camera, "reference", self.settings.reference_points)
            try:
                pts, pix, _ = self.collection.collect(
                    camera, "reference", 0, self.settings.reference_points, plan
                )
            except CampaignAborted as exc:
                self._aborted(exc)
                return self._end()
            if len(pts):
                self.references[camera] = (pts, pix)
        travels = self.bounds.travels
        for count in range(travels + 1):
            goal = yield NextVisit()
            if goal is None:
                break
            if count == travels:
                self._aborted(self.travel.no_progress("travels", count, travels), goal)
                break
            if not (yield from self._go_to(goal)):
                break
        return self._end()

    def _end(self) -> CampaignOutcome:
        """The campaign is over: what it gave."""
        if self.travel.control_points is not None:
            self.travel.control_points.report_unseen(self.rig.parent.name)
        self.journal.stage("done")
        self.outcome.travelled = self.journal.travelled
        return self.outcome

    def _go_to(self, goal: Visit | Return) -> Generator[Question, Any, bool]:
        """Travel to a goal's station and calibrate there if it is a visit; whether the
        campaign goes on."""
        if isinstance(goal, Return):
            self.journal.stage("return", detail=goal.reason or "back to a place measured before")
        else:
            detail = f"to the station of {goal.camera}"
            self.journal.stage("travel", goal.camera, goal.number, detail)
        try:
            reached = yield from self._travel(goal)
        except CampaignAborted as exc:
            self._aborted(exc, goal)
            return False
        if isinstance(goal, Return):
            if not reached:
                self.journal.failure(
                    "return_unreachable", "the parent stopped short", self.rig.parent.name
                )
            return True
        if not reached:
            message = "the parent stopped short"
            self.journal.skipped(
                goal.camera, goal.number, goal.station, "station_unreachable", message
            )
            return True
        self.journal.stage("station", goal.camera, goal.number, f"calibrating {goal.camera}")
        plan: StopPlan = yield DataStops(goal.camera, "visit", self.settings.station_points)
        try:
            self.collection.calibrate(goal.camera, goal.number, goal.station, plan)
        except CampaignAborted as exc:
            self._aborted(exc, goal)
            return False
        return True

    def _aborted(self, exc: CampaignAborted, goal: Visit | Return | None = None) -> None:
        """The campaign cannot go on: a failure, and the visit it was on skipped."""
        self.journal.failure("campaign_aborted", str(exc))
        if isinstance(goal, Visit):
            self.journal.skipped(
                goal.camera, goal.number, goal.station, "campaign_aborted", str(exc)
            )

    def _travel(self, goal: Visit | Return) -> Generator[Question, Any, bool]:
        """CPS legs to the goal's station; whether the parent reached it.

        Raises:
            CampaignAborted: no leg could be planned, or CPS lost the children and could
                not back off (:mod:`.recovery`).
            NoProgress: the strategy asked for more legs than :attr:`bounds` allows, or
                more legs in a row were backed off from.
        """
        legs = self.bounds.legs
        failed: Leg | None = None
        for count in range(legs + 1):
            leg: Leg | NoLeg | None = yield NextLeg(goal, failed)
            failed = None
            if leg is None:
                return True
            if isinstance(leg, NoLeg):
                self.journal.failure(leg.kind, leg.message)
                raise CampaignAborted(leg.reason)
            if count == legs:
                if isinstance(goal, Return):
                    where = goal.reason or "to a place measured before"
                else:
                    where = f"to the station of {goal.camera}"
                raise self.travel.no_progress(f"legs {where}", count, legs)
            try:
                reached = self.travel.execute(leg)
            except LegRecovered:
                failed = leg  # backed off (recorded): the strategy plans it again, shorter
                continue
            if not reached and leg.arrives:
                return False
        raise AssertionError("unreachable: the last pass returns or raises")


def _solver(rig: Rig) -> str:
    """WLS weighs the children by their covariance; an instrument with a noise-free axis
    gives singular covariances, and then the closed form (eq. 2), which needs none."""
    spec, tilt = rig.total_station.spec, rig.total_station.inclinometer
    angles = max(spec.angle_sigma, spec.pointing_sigma)  # either makes the angles noisy
    sigmas = (spec.distance_sigma(1.0), angles, 1.0 if tilt is None else tilt.sigma)
    return "wls" if min(sigmas) > 0 and len(rig.children) > 1 else "closed_form"
