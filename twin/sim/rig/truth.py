"""The simulation records its own truth beside the devices' readings (:mod:`twin.truth`):
each camera's true model at the start, the total station's true pose at the start and
whenever the parent's pose estimate is set from a fix, and each robot's true pose at the
start and after each of its drives."""

from __future__ import annotations

import math

from numpy.typing import ArrayLike

from calib.io.camera_files import camera_to_dict
from twin.hal.devices import Clock, MobileBase
from twin.hal.readings import DriveResult
from twin.hal.recording import Recorder
from twin.hal.wrappers import MobileBaseWrapper
from twin.sim.rig.frames import WorldFrame
from twin.sim.world import World
from twin.truth import TRUTH_CAMERA, TRUTH_INSTRUMENT, TRUTH_ROBOT


class TruthWitness:
    """Writes the world's truth, in W, to a recorder.

    Args:
        recorder: where the truth goes (the run's log).
        world: the world. frame: W in MuJoCo's frame. clock: the rig's clock.
        parent: the parent's name (it carries the instrument).
    """

    def __init__(
        self, recorder: Recorder, world: World, frame: WorldFrame, clock: Clock, parent: str
    ) -> None:
        self.recorder, self.world, self.frame = recorder, world, frame
        self.clock, self.parent = clock, parent

    def cameras(self) -> None:
        """Every camera's true model in W."""
        t = self.clock.now()
        for name in self.world.camera_names:
            truth = self.frame.camera(self.world.camera(name))
            self.recorder.record(TRUTH_CAMERA, {"name": name, "camera": camera_to_dict(truth)}, t)

    def instrument(self) -> None:
        """The total station's true centre and heading in W, now."""
        t = self.clock.now()
        position, rotation = self.world.instrument_pose(self.parent)
        axis = self.frame.mujoco2w @ rotation[:, 0]
        record = {
            "timestamp": t,
            "translation": self.frame.points(position).tolist(),
            "yaw": math.atan2(axis[1], axis[0]),
        }
        self.recorder.record(TRUTH_INSTRUMENT, record, t)

    def robot(self, robot: str) -> None:
        """A robot's base body: its true origin and body-to-W rotation in W, now."""
        t = self.clock.now()
        position, rotation = self.world.body_pose(robot)
        record = {
            "robot": robot,
            "timestamp": t,
            "translation": self.frame.points(position).tolist(),
            "rotation": (self.frame.mujoco2w @ rotation).tolist(),
        }
        self.recorder.record(TRUTH_ROBOT, record, t)


class WitnessedBase(MobileBaseWrapper):
    """A robot's base: after each drive, its true pose is recorded."""

    def __init__(self, inner: MobileBase, witness: TruthWitness) -> None:
        super().__init__(inner)
        self.witness = witness

    def drive_to(self, goal_xy: ArrayLike, goal_yaw: float | None = None) -> DriveResult:
        try:
            return self.inner.drive_to(goal_xy, goal_yaw)
        finally:
            self.witness.robot(self.inner.name)


class WitnessedParent(MobileBaseWrapper):
    """The parent's base: after its pose estimate is set (a CPS fix), the instrument's true
    pose is recorded beside it."""

    def __init__(self, inner: MobileBase, witness: TruthWitness) -> None:
        super().__init__(inner)
        self.witness = witness

    def set_pose(self, x: float, y: float, yaw: float) -> None:
        self.inner.set_pose(x, y, yaw)
        self.witness.instrument()
