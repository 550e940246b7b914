"""The robots' bases in the world, at both fidelities.

A base drives to goals in W by its own localisation: wheel odometry (render fidelity) or
its belief that it stopped where it was sent (geometric fidelity), corrected by
:meth:`set_pose` when the campaign has a fix. The truth is the world's.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from calib.rotation import compose_planar, invert_planar, wrap_angle
from twin.hal.devices import Clock, MobileBase
from twin.hal.readings import DriveResult, DriveStatus, OdometryReading
from twin.scenario.geometry import inside_obstacles, inside_space
from twin.scenario.schema import StoppingConfig
from twin.sim.rig.frames import WorldFrame
from twin.sim.world import World
from twin.timing import timed

UNREACHABLE_RADIUS = 0.5
"""A goal within this distance of a scenario's ``faults.unreachable`` point cannot be
reached, m."""

BLOCKED_SHORT_OF = 1.5
"""A base that finds its goal blocked stops this far short of it (or where it is), m."""


def _check_pose(x: float, y: float, yaw: float) -> None:
    if not all(math.isfinite(v) for v in (x, y, yaw)):
        raise ValueError(f"a pose fix must be finite, got x={x}, y={y}, yaw={yaw}")


class _SimBase(MobileBase):
    """What both fidelities share: the name, the unreachable goals, the pose records."""

    def __init__(
        self, world: World, name: str, frame: WorldFrame, clock: Clock, unreachable: ArrayLike
    ) -> None:
        self.world = world
        self._name = name
        self.frame = frame
        self.clock = clock
        self.unreachable = np.asarray(unreachable, dtype=float).reshape(-1, 2)
        self.radius = world.robots[name].platform.radius

    @property
    def name(self) -> str:
        return self._name

    def _reading(self, pose: np.ndarray) -> OdometryReading:
        return OdometryReading(
            self._name,
            self.clock.now(),
            float(pose[0]),
            float(pose[1]),
            float(wrap_angle(pose[2])),
        )

    def _blocked(self, goal: np.ndarray) -> str:
        """Why ``goal`` (W, (2,)) cannot be reached, or ""."""
        if (
            len(self.unreachable)
            and np.min(np.linalg.norm(self.unreachable - goal, axis=1)) <= UNREACHABLE_RADIUS
        ):
            return "the way to the goal is blocked"
        xy = self.frame.pose_to_mujoco([goal[0], goal[1], 0.0])[:2]
        space = self.world.scenario.space
        if not inside_space(space, xy[None], self.radius)[0]:
            return "the goal is outside the space"
        inside = np.flatnonzero(inside_obstacles(space.obstacles, xy[None], self.radius)[:, 0])
        if inside.size:
            return f"the goal is inside obstacle {space.obstacles[inside[0]].name!r}"
        return ""

    @staticmethod
    def _short_of(start: np.ndarray, goal: np.ndarray) -> np.ndarray:
        d = goal - start
        n = float(np.linalg.norm(d))
        if n <= BLOCKED_SHORT_OF:
            return start.copy()
        return start + d * (n - BLOCKED_SHORT_OF) / n

    def close(self) -> None:
        self.world.driving.stop(self._name)


class RenderBase(_SimBase):
    """A base driven in MuJoCo by its controller on wheel odometry (render fidelity).

    Args:
        world, name: the world and the robot. frame: W in MuJoCo's frame.
        clock: the rig's clock. timings: accumulates the wall time of physics.
        unreachable: (K, 2) goals in W that a drive cannot reach.
    """

    def __init__(
        self,
        world: World,
        name: str,
        frame: WorldFrame,
        clock: Clock,
        timings: dict[str, float],
        unreachable: ArrayLike = (),
    ) -> None:
        super().__init__(world, name, frame, clock, unreachable)
        self.timings = timings
        # The base's localisation: W pose = correction (x) odometry pose (MuJoCo frame).
        self._correction = frame.pose(np.zeros(3))

    def _believed(self) -> np.ndarray:
        return compose_planar(self._correction, self.world.driving.odometry[self._name].pose)

    def odometry(self) -> OdometryReading:
        return self._reading(self._believed())

    def set_pose(self, x: float, y: float, yaw: float) -> None:
        _check_pose(x, y, yaw)
        odo = self.world.driving.odometry[self._name].pose
        self._correction = compose_planar(np.array([x, y, yaw], dtype=float), invert_planar(odo))

    def drive_to(self, goal_xy: ArrayLike, goal_yaw: float | None = None) -> DriveResult:
        g = np.asarray(goal_xy, dtype=float).reshape(2)
        goal = np.array([g[0], g[1], np.nan if goal_yaw is None else float(goal_yaw)])
        start = self.clock.now()
        why = self._blocked(g)
        target = g if not why else self._short_of(self._believed()[:2], g)
        # The goal in the odometry's frame.
        inv = invert_planar(self._correction)
        yaw = 0.0 if goal_yaw is None else float(goal_yaw)
        local = compose_planar(inv, np.array([target[0], target[1], yaw]))
        with timed(self.timings, "physics"):
            result = self.world.drive_to(
                self._name,
                local[:2],
                None if goal_yaw is None or why else float(local[2]),
                pose_source="odometry",
            )
        status = DriveStatus(result.status)
        message = ""
        if why:
            status, message = DriveStatus.BLOCKED, why
        elif status is DriveStatus.FELL_OVER:
            message = "tipped over"
        elif result.collisions:
            c = result.collisions[0]
            message = f"touched {c.other} at t = {c.time:.1f} s"
        return DriveResult(
            robot=self._name,
            timestamp=self.clock.now(),
            goal=goal,
            status=status,
            odometry=self.odometry(),
            duration=self.clock.now() - start,
            message=message,
        )


class GeometricBase(_SimBase):
    """A base placed at its goal with a stopping error (geometric fidelity).

    The base believes it stopped exactly at the goal; the truth differs by the stopping
    error. The clock advances by the travel time at the platform's top speed.

    Args:
        world, name, frame, clock: as :class:`RenderBase`.
        stopping: the stopping error. rng: its random generator.
        unreachable: (K, 2) goals in W that a drive cannot reach.
        timings: accumulates the wall time of placing (``physics``).
    """

    def __init__(
        self,
        world: World,
        name: str,
        frame: WorldFrame,
        clock: Clock,
        stopping: StoppingConfig,
        rng: np.random.Generator,
        timings: dict[str, float],
        unreachable: ArrayLike = (),
    ) -> None:
        super().__init__(world, name, frame, clock, unreachable)
        self.stopping = stopping
        self.rng = rng
        self.timings = timings
        self._belief = frame.pose(world.robot_pose(name))

    def odometry(self) -> OdometryReading:
        return self._reading(self._belief)

    def set_pose(self, x: float, y: float, yaw: float) -> None:
        _check_pose(x, y, yaw)
        self._belief = np.array([x, y, yaw], dtype=float)

    def drive_to(self, goal_xy: ArrayLike, goal_yaw: float | None = None) -> DriveResult:
        g = np.asarray(goal_xy, dtype=float).reshape(2)
        goal = np.array([g[0], g[1], np.nan if goal_yaw is None else float(goal_yaw)])
        start = self.clock.now()
        why = self._blocked(g)
        here = self._belief[:2]
        target = g if not why else self._short_of(here, g)
        travel = float(np.linalg.norm(target - here))
        if goal_yaw is None or why:
            yaw = math.atan2(*(target - here)[::-1]) if travel > 1e-6 else self._belief[2]
        else:
            yaw = float(goal_yaw)
        believed = np.array([target[0], target[1], yaw])
        # Where it really stops: the believed pose mapped through the truth's offset from
        # the belief, plus the stopping error.
        true_now = self.frame.pose(self.world.robot_pose(self._name))
        offset = compose_planar(true_now, invert_planar(self._belief))
        truth = compose_planar(offset, believed)
        truth[:2] += self.stopping.sigma_xy * self.rng.standard_normal(2)
        truth[2] += self.stopping.sigma_yaw * self.rng.standard_normal()
        mj = self.frame.pose_to_mujoco(truth)
        with timed(self.timings, "physics"):
            self.world.place(self._name, mj[:2], float(mj[2]), hold_others=True)
        if hasattr(self.clock, "pass_time"):
            self.clock.pass_time(travel / self.world.robots[self._name].platform.max_speed)
        self._belief = believed
        return DriveResult(
            robot=self._name,
            timestamp=self.clock.now(),
            goal=goal,
            status=DriveStatus.BLOCKED if why else DriveStatus.REACHED,
            odometry=self.odometry(),
            duration=self.clock.now() - start,
            message=why,
        )
