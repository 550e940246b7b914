"""The campaign's recorded steps, which the batch fidelity replays: what the geometric
fidelity does without noise, recorded once per scenario and strategy (the plan).

:func:`record_plan` runs the campaign at the geometric fidelity with every noise source off
(the instrument still advertises the scenario's noise, so the campaign weighs its data and
solves CPS as in a real run), and records, in the order they happen:

- every drive of a base: where the base believes it stopped, and where it truly stopped
  (for a child, its corner cubes and LEDs in W; for the parent, its instrument's centre
  and orientation in W);
- every placement of a child in the CPS state (:class:`Place`: three shots at its cubes
  from the standing parent), every fix of the parent (:class:`Fix`: three shots at each
  child it was solved from);
- every data point (:class:`Point`: the child's LEDs seen by a camera at its last
  placement, and which of them the camera found: all of them with ``campaign.data_stops =
  "all_leds"``, those in the image with ``"accuracy"``), every data set and every
  calibration.

The batch executes this plan for many trials at once (:mod:`twin.batch.execute`), each with
its own noise. Decisions are not taken again under noise: where a trial's noise would
change a decision of the campaign (a re-aim after a lost lock, another stop in place of one
where an LED fell out of view, a retried fix, an LED that came into view at a stop planned
without it, the stops for accuracy planned from noisy estimates), the batch keeps the
noise-free decision.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from calib.camera import TsaiCamera
from calib.io.camera_files import camera_from_dict
from twin.campaign import Campaign
from twin.campaign.records import (
    CALIBRATION,
    CHILD_PLACED,
    DATASET,
    PARENT_FIX,
    POINT,
    CalibrationRecord,
)
from twin.campaign.strategies import strategy_for
from twin.campaign.strategy import CampaignView, Question, Strategy
from twin.hal.devices import MobileBase
from twin.hal.readings import DriveResult
from twin.hal.recording import recorded
from twin.hal.wrappers import MobileBaseWrapper, wrapped
from twin.scenario.schema import Scenario
from twin.sim.capture import led_radii
from twin.sim.rig import SimRig, build_sim_rig
from twin.sim.robots import N_LEDS
from twin.sim.world import build_world


@dataclass(frozen=True)
class RobotTruth:
    """Where a robot truly stands, in W.

    Attributes:
        pose: (3,) planar pose (x m, y m, yaw rad) of its body origin.
        cubes, leds: (3, 3) and (N_led, 3) its marker's corner cubes and LEDs, m (a child).
        instrument: (3,) the instrument's centre, m (the parent).
        instrument2world: (3, 3) the instrument's orientation, tilt included (the parent).
    """

    pose: NDArray[np.float64]
    cubes: NDArray[np.float64] | None = None
    leds: NDArray[np.float64] | None = None
    instrument: NDArray[np.float64] | None = None
    instrument2world: NDArray[np.float64] | None = None


@dataclass(frozen=True)
class Drive:
    """A base drove: ``believed`` (3,) is its pose estimate after the drive (the goal it
    was sent to), ``truth`` where it stood in the noise-free run."""

    robot: str
    believed: NDArray[np.float64]
    truth: RobotTruth


@dataclass(frozen=True)
class Place:
    """The standing parent measured a child's three cubes and placed it in the CPS state;
    the child's pose estimate was corrected from its marker's pose."""

    child: str


@dataclass(frozen=True)
class Fix:
    """The parent measured these children (three cubes each, in this order) and solved its
    pose; its pose estimate was corrected from the solution."""

    children: tuple[str, ...]


@dataclass(frozen=True)
class Point:
    """A camera found the LEDs of a child at its last placement: a data point.

    ``leds`` are the indices of the child's LEDs the camera found there without noise, in
    order: the point's LED points (every LED where the stop's plan needs them all, those in
    the image at a stop chosen for accuracy). ``partial``: whether the stop's plan takes a
    point from the LEDs found where not all are (a trial that misses a planned LED then
    loses that LED, not the whole stop)."""

    dataset: str
    camera: str
    visit: int
    child: str
    leds: tuple[int, ...] = tuple(range(N_LEDS))
    partial: bool = False


@dataclass(frozen=True)
class DataSetDone:
    """A data set is complete: its first ``points`` LED points are the set."""

    dataset: str
    camera: str
    visit: int
    points: int


@dataclass(frozen=True)
class Calibrate:
    """The camera was calibrated from its visit's data set (``points`` LED points);
    ``nominal`` is the noise-free calibration (every trial's start)."""

    camera: str
    visit: int
    points: int
    nominal: TsaiCamera


Step = Drive | Place | Fix | Point | DataSetDone | Calibrate


@dataclass(frozen=True)
class BatchPlan:
    """The campaign of a scenario, as its strategy chose it without noise.

    Attributes:
        scenario: the scenario (with its noise, which the plan was recorded without).
        strategy: the strategy's name.
        parent: the parent's name. children: the children's names, in the rig's order.
        start: each robot's truth at the first station (W is the parent's instrument frame
            there).
        steps: what the campaign did, in order.
        cameras: each camera's true model in W.
        led_radii: each child's (N_led,) LED radii, m (an LED is seen whole or not at all).
    """

    scenario: Scenario
    strategy: str
    parent: str
    children: tuple[str, ...]
    start: Mapping[str, RobotTruth]
    steps: tuple[Step, ...]
    cameras: Mapping[str, TsaiCamera]
    led_radii: Mapping[str, NDArray[np.float64]]

    @property
    def calibrations(self) -> tuple[Calibrate, ...]:
        """The calibrations of the plan, in order."""
        return tuple(s for s in self.steps if isinstance(s, Calibrate))

    def count(self, kind: type) -> int:
        """How many steps of a kind the plan holds."""
        return sum(isinstance(s, kind) for s in self.steps)


def _truth(sim: SimRig, robot: str) -> RobotTruth:
    """Where ``robot`` stands now, in W."""
    world, frame = sim.world, sim.frame
    pose = frame.pose(world.robot_pose(robot))
    if robot == sim.rig.parent.name:
        position, rotation = world.instrument_pose(robot)
        return RobotTruth(
            pose, instrument=frame.points(position), instrument2world=frame.mujoco2w @ rotation
        )
    cubes, leds = world.marker_points(robot)
    return RobotTruth(pose, cubes=frame.points(cubes), leds=frame.points(leds))


class _Recorder:
    """Keeps the records of the run in order (topic, record)."""

    def __init__(self) -> None:
        self.records: list[tuple[str, Any]] = []

    def record(self, topic: str, record: object, timestamp: float) -> None:
        self.records.append((topic, record))


TRUTH_AFTER_DRIVE = "/plan/truth"


class _Witness(MobileBaseWrapper):
    """A base that records where it truly stopped after each drive."""

    def __init__(self, inner: MobileBase, sim: SimRig, recorder: _Recorder) -> None:
        super().__init__(inner)
        self.sim, self.recorder = sim, recorder

    def drive_to(self, goal_xy, goal_yaw=None) -> DriveResult:
        result = self.inner.drive_to(goal_xy, goal_yaw)
        self.recorder.record(TRUTH_AFTER_DRIVE, (self.name, _truth(self.sim, self.name)), 0.0)
        return result


class PlanSession:
    """The campaign of a scenario without noise, advanced one decision at a time.

    The campaign asks its questions (:class:`twin.campaign.strategy.Question`: which
    reference cameras, which visit next, which leg, which formation...) one by one;
    :meth:`answer` sends an answer and returns the plan's steps the campaign took until its
    next question. A batch of trials (:class:`twin.batch.execute.BatchRun`) executes those
    steps, so a caller (an environment whose agent takes the decisions, or the strategy
    itself: :meth:`suggested`) advances a batch of episodes one decision at a time.
    :func:`record_plan` answers every question with the strategy's answer.

    Args:
        scenario: the scenario, with its noise (the instrument advertises it).
        strategy: the strategy that :meth:`suggested` asks, by name or as an instance
            that serves this session only (default: the scenario's).

    The session holds a MuJoCo world: :meth:`close` it (or use it as a context manager).
    """

    def __init__(self, scenario: Scenario, strategy: str | Strategy | None = None) -> None:
        self.scenario = scenario
        self.strategy = (
            strategy if isinstance(strategy, Strategy) else strategy_for(scenario, strategy)
        )
        quiet = scenario.without_noise()
        world = build_world(quiet)
        self._probe: NDArray[np.float64] | None = None  # the world's state for truth_at
        self._recorder = _Recorder()
        self._sim = build_sim_rig(world, "geometric", advertised=scenario.noise)
        try:
            sim = self._sim
            names = (sim.rig.parent.name, *sim.rig.children)
            self._start = {name: _truth(sim, name) for name in names}
            self._cameras = {n: sim.frame.camera(world.camera(n)) for n in world.camera_names}
            radii = led_radii(world)
            self._parent, self._children = sim.rig.parent.name, tuple(sim.rig.children)
            self._radii = {
                c: np.array([radii[(c, k)] for k in range(N_LEDS)]) for c in self._children
            }
            devices = wrapped(sim.rig, base=lambda base: _Witness(base, sim, self._recorder))
            rig = recorded(devices, self._recorder)
            self._campaign = Campaign(rig, quiet, self._recorder, strategy=self.strategy)
            self.strategy.start(self._campaign.view)
            self._generator = self._campaign.steps()
            self._parser = _StepParser()
            self.question: Question | None = None
            self._advance(lambda: next(self._generator))
        except BaseException:
            self._sim.close()
            raise

    @property
    def view(self) -> CampaignView:
        """What a strategy may look at to answer :attr:`question`."""
        return self._campaign.view

    @property
    def time(self) -> float:
        """The campaign's time so far by the simulated clock (drives, shots, frames), s."""
        return self._sim.rig.clock.now()

    @property
    def travelled(self) -> float:
        """The parent's travel so far, m (between its fixed stations)."""
        return self._campaign.journal.travelled

    @property
    def done(self) -> bool:
        """Whether the campaign has finished (no question left)."""
        return self.question is None

    def suggested(self) -> object:
        """The strategy's answer to the current question."""
        if self.question is None:
            raise RuntimeError("the campaign has finished: no question to answer")
        return self.question.ask(self.strategy, self.view)

    def answer(self, answer: object) -> tuple[Step, ...]:
        """Answer the current question; the steps the campaign took until its next one."""
        if self.question is None:
            raise RuntimeError("the campaign has finished: no question to answer")
        before = len(self._parser.steps)
        self._advance(lambda: self._generator.send(answer))
        return tuple(self._parser.steps[before:])

    def _advance(self, resume: Any) -> None:
        try:
            self.question = resume()
        except StopIteration:
            self.question = None
        self._parser.feed(self._recorder.records)
        self._recorder.records.clear()

    @property
    def plan(self) -> BatchPlan:
        """The plan so far (its steps those the campaign has taken)."""
        return BatchPlan(
            scenario=self.scenario,
            strategy=self.strategy.name,
            parent=self._parent,
            children=self._children,
            start=self._start,
            steps=tuple(self._parser.steps),
            cameras=self._cameras,
            led_radii=self._radii,
        )

    def truth_at(self, robot: str, pose: NDArray[np.float64]) -> RobotTruth:
        """Where ``robot`` truly stands when placed at the planar ``pose`` (3,) (x m, y m,
        yaw rad in W): its marker or its instrument on the floor there, tilt included.

        The robot is moved in the session's world: ask this of a session whose campaign is
        over (a probe of the site), not of one that goes on. Each answer starts from the
        world as it was at the first question (the robots where the campaign left them), so
        that it does not depend on the questions asked before.
        """
        sim = self._sim
        model, data = sim.world.model, sim.world.data
        what = mujoco.mjtState.mjSTATE_INTEGRATION
        if self._probe is None:
            self._probe = np.empty(mujoco.mj_stateSize(model, what))
            mujoco.mj_getState(model, data, self._probe, what)
        mujoco.mj_setState(model, data, self._probe, what)
        mujoco.mj_forward(model, data)
        for name in sim.world.robots:  # at rest where they stand, wheels held from there
            sim.world.driving.stop(name)
            sim.world.driving.put_down(name)
        mj = sim.frame.pose_to_mujoco(np.asarray(pose, dtype=float).reshape(3))
        sim.world.place(robot, mj[:2], float(mj[2]), hold_others=True)
        return _truth(sim, robot)

    def max_speed(self, robot: str) -> float:
        """The robot's top speed, m/s (the geometric clock counts a drive's straight travel
        at it)."""
        return float(self._sim.world.robots[robot].platform.max_speed)

    def close(self) -> None:
        """Free the world."""
        self._sim.close()

    def __enter__(self) -> PlanSession:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def record_plan(scenario: Scenario, strategy: str | None = None) -> BatchPlan:
    """Run the campaign of ``scenario`` once at the geometric fidelity without noise, every
    decision its strategy's, and record its plan (see the module).

    Args:
        scenario: the scenario, with its noise (the instrument advertises it).
        strategy: the campaign's strategy by name (default: the scenario's).
    """
    with PlanSession(scenario, strategy) as session:
        while not session.done:
            session.answer(session.suggested())
        return session.plan


class _StepParser:
    """Turns a run's records into the plan's steps, as they come."""

    def __init__(self) -> None:
        self.steps: list[Step] = []
        self._truth: dict[str, RobotTruth] = {}
        self._found: dict[tuple[str, str], tuple[int, ...]] = {}  # (camera, child) -> LEDs

    def feed(self, records: list[tuple[str, Any]]) -> None:
        """Parse the next records, in order."""
        for topic, rec in records:
            self._one(topic, rec)

    def _one(self, topic: str, rec: Any) -> None:
        steps, truth = self.steps, self._truth
        if topic == TRUTH_AFTER_DRIVE:
            name, where = rec
            truth[name] = where
        elif topic.startswith("/base/") and topic.endswith("/drive"):
            steps.append(Drive(rec.robot, rec.odometry.pose, truth.pop(rec.robot)))
        elif topic == CHILD_PLACED:
            steps.append(Place(rec.child))
        elif topic == PARENT_FIX and rec.children:
            steps.append(Fix(tuple(rec.children)))
        elif topic.startswith("/camera/") and topic.endswith("/leds"):
            self._found[(rec.camera, rec.child)] = tuple(np.flatnonzero(rec.found).tolist())
        elif topic == POINT:
            leds = self._found.pop((rec.camera, rec.child), None)
            if leds is None or len(leds) != len(rec.leds_world):
                raise RuntimeError(
                    f"data point of {rec.child} at {rec.camera} (visit {rec.visit}): "
                    f"{len(rec.leds_world)} LED points, but the camera's last observation "
                    f"found LEDs {leds}"
                )
            steps.append(Point(rec.dataset, rec.camera, rec.visit, rec.child, leds, rec.partial))
        elif topic == DATASET:
            steps.append(DataSetDone(rec.dataset, rec.camera, rec.visit, rec.points))
        elif topic == CALIBRATION:
            assert isinstance(rec, CalibrationRecord)
            model = camera_from_dict(rec.camera_model, f"calibration of {rec.camera}")
            assert isinstance(model, TsaiCamera)
            steps.append(Calibrate(rec.camera, rec.visit, rec.points, model))
