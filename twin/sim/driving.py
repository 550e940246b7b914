"""Driving the robots of a world: velocity commands within the platforms' limits, the
go-to-pose controllers, the wheels' hold at rest, wheel odometry and collisions.

:class:`Driving` acts on a world's MuJoCo model and data; the world calls it around each
physics step (:meth:`twin.sim.world.World.step`): :meth:`Driving.control` and
:meth:`Driving.apply_commands` before, :meth:`Driving.update_odometry` and
:meth:`Driving.detect_collisions` after.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.scenario.robots import OdometrySpec
from twin.sim.controller import DriveController, DriveTolerance, ramp
from twin.sim.odometry import WheelOdometry
from twin.sim.robots import RobotHandle

ODOMETRY_STREAM = 1
"""Stream of numpy.random.SeedSequence reserved for odometry errors."""

COLLISION_DEBOUNCE_TICKS = 25
"""A robot touching the same geom again within this many control periods of their last
contact is the same collision (contacts flicker while a robot pushes against something)."""

HOLD_GAIN = 10.0
"""Gain of the wheels' position hold at rest, 1/s: a stopped robot's motor controller
commands each side's wheels the speed ``-HOLD_GAIN * (side's mean angle - its angle at
rest)``, as the Pioneers' controllers hold their wheels at zero speed with an integral
term. Without it the wheels of a parked robot roll freely against their speed servos'
damping: a P3-DX child whose wheels rested on the 1.5 mm edge of a tilted floor patch
rolled 12-20 mm off it in 30 s, enough for the parent's next CPS fix to fail its
consistency test."""

POSE_SOURCES = ("truth", "odometry")
"""Where a controller reads the robot's pose: the simulator's truth (standing in for an
external positioning system such as CPS) or its own wheel odometry (dead reckoning)."""


@dataclass(frozen=True)
class Collision:
    """A robot's chassis touching a wall, an obstacle or another robot.

    Attributes:
        time: simulation time when the contact was first seen, s.
        robot: the robot's name.
        other: name of the geom it touched (e.g. ``wall_north``, ``pillar``, ``child2/chassis``).
        position: (3,) contact point in the world frame, m.
    """

    time: float
    robot: str
    other: str
    position: NDArray[np.float64] = field(repr=False)


class Driving:
    """The robots' motion commands, controllers, wheel hold, odometry and collisions.

    Args:
        model, data: the world's MuJoCo objects.
        robots: handle of each robot by name.
        control_period: period of the controllers and odometry updates, s.

    Attributes:
        odometry: wheel odometry of each robot by name (set by :meth:`reset`).
        collisions: every collision seen so far, in time order.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        robots: Mapping[str, RobotHandle],
        control_period: float,
    ) -> None:
        self.model, self.data = model, data
        self.robots = robots
        self.control_period = control_period
        self._chassis_robot = {h.chassis: h.name for h in robots.values()}
        self._is_chassis = np.zeros(model.ngeom, dtype=bool)
        self._is_chassis[list(self._chassis_robot)] = True
        self.odometry: dict[str, WheelOdometry] = {}
        self.collisions: list[Collision] = []

    def reset(self, seed: int, odometry: OdometrySpec) -> None:
        """Every robot at rest with no goal; odometry started at the true poses, its
        errors drawn from ``seed``."""
        seeds = np.random.SeedSequence(seed, spawn_key=(ODOMETRY_STREAM,))
        self.odometry = {}
        for (name, handle), child_seed in zip(
            self.robots.items(), seeds.spawn(len(self.robots)), strict=True
        ):
            self.odometry[name] = WheelOdometry(
                handle.platform.wheel_radius,
                handle.platform.effective_track,
                odometry,
                np.random.default_rng(child_seed),
                pose=handle.pose(self.data),
            )
        self._wheels = {n: h.wheel_angles(self.data) for n, h in self.robots.items()}
        self._held: dict[str, tuple[float, float]] = {}  # (left, right) wheel angles held, rad
        self._controllers: dict[str, DriveController] = {}
        self._pose_source: dict[str, str] = {}
        self._last_contact: dict[tuple[str, int], int] = {}
        self._tick = 0
        self._target = {n: (0.0, 0.0) for n in self.robots}
        self._command = {n: (0.0, 0.0) for n in self.robots}
        self.collisions = []

    def put_down(self, robot: str) -> None:
        """A robot was put somewhere by hand: its odometry starts again at its true pose
        and its wheels are held from their new angles."""
        h = self.robots[robot]
        self.odometry[robot].reset(h.pose(self.data))
        self._wheels[robot] = h.wheel_angles(self.data)
        self._held.pop(robot, None)

    # -- commands ------------------------------------------------------------------------
    def set_body_velocity(self, robot: str, v: float, w: float) -> None:
        """Command a forward speed (m/s) and a yaw rate (rad/s).

        The command is clipped to the robot's speed and turn-rate limits and reached at
        its acceleration limits, from the next step on: each control period the applied
        (v, w) moves towards it by at most ``max_accel`` and ``max_yaw_accel`` times the
        period. The applied (v, w) becomes wheel speeds through the robot's
        ``command_track``.
        """
        p = self.robots[robot].platform
        self._target[robot] = (
            float(np.clip(v, -p.max_speed, p.max_speed)),
            float(np.clip(w, -p.max_yaw_rate, p.max_yaw_rate)),
        )

    def body_velocity_command(self, robot: str) -> tuple[float, float]:
        """The (v, w) applied to the robot's wheels in the last control period."""
        return self._command[robot]

    def drive(
        self,
        robot: str,
        goal_xy: ArrayLike,
        goal_yaw: float | None = None,
        pose_source: str = "truth",
        tolerance: DriveTolerance | None = None,
    ) -> DriveController:
        """Start driving ``robot`` to a goal; each step then runs its controller.

        Args:
            robot: the robot's name.
            goal_xy: (x, y) goal of the body origin, m.
            goal_yaw: goal heading, rad (None: keep the arrival heading).
            pose_source: one of :data:`POSE_SOURCES`.
            tolerance: when the goal counts as reached.
        """
        if pose_source not in POSE_SOURCES:
            raise ValueError(f"pose_source must be 'truth' or 'odometry', got {pose_source!r}")
        g = np.asarray(goal_xy, dtype=float).reshape(2)
        ctl = DriveController(self.robots[robot].platform, (g[0], g[1]), goal_yaw, tolerance)
        self._controllers[robot] = ctl
        self._pose_source[robot] = pose_source
        return ctl

    def stop(self, robot: str) -> None:
        """Cancel the robot's goal and stop its wheels at once (an emergency stop: the
        acceleration limit does not apply)."""
        self._controllers.pop(robot, None)
        self._target[robot] = self._command[robot] = (0.0, 0.0)
        self._set_ctrl(self.robots[robot], 0.0, 0.0)

    def moving(self) -> list[str]:
        """Names of the robots that have a goal not yet reached."""
        return [n for n, c in self._controllers.items() if not c.done]

    # -- around each physics step ----------------------------------------------------------
    def control(self) -> None:
        """Run each robot's controller on its pose: new velocity targets."""
        self._tick += 1
        for name, ctl in self._controllers.items():
            if ctl.done:
                self.set_body_velocity(name, 0.0, 0.0)
                continue
            if self._pose_source[name] == "truth":
                pose = self.robots[name].pose(self.data)
            else:
                pose = self.odometry[name].pose
            v, w = ctl.update((pose[0], pose[1], pose[2]), self.control_period)
            self.set_body_velocity(name, v, w)

    def apply_commands(self) -> None:
        """Ramp each robot's (v, w) towards its target and set its wheel speeds; a robot
        at rest holds its wheels."""
        dt = self.control_period
        for name, h in self.robots.items():
            p = h.platform
            v0, w0 = self._command[name]
            vt, wt = self._target[name]
            # The controllers ramp by exactly these steps: allow for rounding.
            v = ramp(v0, vt, p.max_accel * dt * (1.0 + 1e-9))
            w = ramp(w0, wt, p.max_yaw_accel * dt * (1.0 + 1e-9))
            self._command[name] = (v, w)
            if v == 0.0 and w == 0.0 and vt == 0.0 and wt == 0.0:
                self._hold(h)
                continue
            self._held.pop(name, None)
            half = 0.5 * p.command_track
            self._set_ctrl(h, (v - w * half) / p.wheel_radius, (v + w * half) / p.wheel_radius)

    def _hold(self, h: RobotHandle) -> None:
        """At rest: command each side's wheels back to the mean angle the side had when the
        robot stopped (one command per side, as the motor controller drives them: holding
        the wheels of one side each to its own angle would set them against each other
        through the floor, and a skid-steered robot would slowly turn)."""
        left, right = h.wheel_angles(self.data)
        held_l, held_r = self._held.setdefault(h.name, (left, right))
        self._set_ctrl(h, -HOLD_GAIN * (left - held_l), -HOLD_GAIN * (right - held_r))

    def _set_ctrl(self, h: RobotHandle, left: float, right: float) -> None:
        for a in h.left_act:
            self.data.ctrl[a] = left
        for a in h.right_act:
            self.data.ctrl[a] = right

    def update_odometry(self) -> None:
        """Integrate each robot's wheel turns since the last step into its odometry."""
        for name, h in self.robots.items():
            left, right = h.wheel_angles(self.data)
            l0, r0 = self._wheels[name]
            self.odometry[name].update(left - l0, right - r0)
            self._wheels[name] = (left, right)

    def detect_collisions(self) -> list[Collision]:
        """Contacts of a chassis with anything; a (robot, geom) pair counts as a new
        collision unless it was in contact within the last ``COLLISION_DEBOUNCE_TICKS``.

        Returns:
            The collisions that began in this step (also appended to :attr:`collisions`).
        """
        n = self.data.ncon
        new: list[Collision] = []
        if n:
            g1 = self.data.contact.geom1[:n]
            g2 = self.data.contact.geom2[:n]
            seen: set[tuple[str, int]] = set()
            for k in np.flatnonzero(self._is_chassis[g1] | self._is_chassis[g2]):
                a, b = int(g1[k]), int(g2[k])
                for mine, other in ((a, b), (b, a)):
                    if not self._is_chassis[mine]:
                        continue
                    key = (self._chassis_robot[mine], other)
                    if key in seen:
                        continue
                    seen.add(key)
                    last = self._last_contact.get(key)
                    self._last_contact[key] = self._tick
                    if last is not None and self._tick - last <= COLLISION_DEBOUNCE_TICKS:
                        continue
                    name = mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_GEOM, other)
                    pos = self.data.contact.pos[k].copy()
                    new.append(
                        Collision(float(self.data.time), key[0], name or f"geom{other}", pos)
                    )
        self.collisions += new
        return new
