"""A Pioneer in the twin's world, moved by velocity commands: what an emulated ARCOS robot
drives.

The body keeps two poses: the truth (MuJoCo's frame, where the world shows the robot) and
the wheel odometry (ARCOS' frame, zero where the session opened). Both follow one unicycle;
when the robot comes to rest after moving, the truth is displaced from the odometry by one
draw of the stopping error (as the geometric fidelity's bases stop). A step that would put
the footprint outside the space, into an obstacle or near a scenario's unreachable point is
not taken and the wheels report a stall.
"""

from __future__ import annotations

import math
import threading

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.scenario.geometry import inside_obstacles, inside_space
from twin.scenario.schema import StoppingConfig
from twin.sim.controller import ramp
from twin.sim.rig.frames import WorldFrame
from twin.sim.world import World

UNREACHABLE_RADIUS = 0.5
"""The robot cannot come within this distance of a scenario's unreachable point, m."""

REST_SPEED = 1e-6
"""Below this forward speed (m/s) and turn rate (rad/s) the robot is at rest."""


def _wrap(angle: float) -> float:
    return math.atan2(math.sin(angle), math.cos(angle))


class PioneerBody:
    """One robot of the world, driven kinematically.

    Args:
        world: the world. name: the robot. frame: W in MuJoCo's frame.
        lock: held while the world is read or changed (the world is shared by threads).
        stopping: the stopping error drawn at each stop. rng: its random generator.
        unreachable: (K, 2) points in W the robot cannot come within 0.5 m of.
        max_speed: forward speed limit, m/s (default and at most the platform's).
    """

    def __init__(
        self,
        world: World,
        name: str,
        frame: WorldFrame,
        lock: threading.RLock,
        *,
        stopping: StoppingConfig,
        rng: np.random.Generator,
        unreachable: ArrayLike = (),
        max_speed: float | None = None,
    ) -> None:
        self.world = world
        self.name = name
        self.frame = frame
        self.lock = lock
        self.stopping = stopping
        self.rng = rng
        self.platform = world.robots[name].platform
        self.radius = self.platform.radius
        self.max_speed = (
            self.platform.max_speed
            if max_speed is None
            else min(max_speed, self.platform.max_speed)
        )
        points = np.asarray(unreachable, dtype=float).reshape(-1, 2)
        if len(points):
            self.unreachable = frame.points_to_mujoco(
                np.column_stack([points, np.zeros(len(points))])
            )
            self.unreachable = self.unreachable[:, :2]
        else:
            self.unreachable = np.zeros((0, 2))
        with lock:
            self.truth: NDArray[np.float64] = np.asarray(world.robot_pose(name), float).copy()
        self.odometry: NDArray[np.float64] = np.zeros(3)
        self.v = 0.0
        self.w = 0.0
        self.stalled = False
        self._moved = False  # moved since it last came to rest

    # -- state -----------------------------------------------------------------------------------
    @property
    def moving(self) -> bool:
        """Whether the wheels turn."""
        return abs(self.v) > REST_SPEED or abs(self.w) > REST_SPEED

    @property
    def wheel_speeds(self) -> tuple[float, float]:
        """(left, right) wheel speeds, m/s."""
        half = 0.5 * self.platform.track * self.w
        return self.v - half, self.v + half

    def reset_odometry(self) -> None:
        """Zero the odometry where the robot stands (ARCOS does at OPEN)."""
        self.odometry = np.zeros(3)

    def halt(self) -> None:
        """Stop at once (an emergency stop)."""
        was = self.moving
        self.v = self.w = 0.0
        if was or self._moved:
            self._come_to_rest()

    # -- motion -----------------------------------------------------------------------------------
    def _blocked(self, xy: np.ndarray) -> bool:
        space = self.world.scenario.space
        if not inside_space(space, xy[None], self.radius)[0]:
            return True
        if inside_obstacles(space.obstacles, xy[None], self.radius).any():
            return True
        return bool(
            len(self.unreachable)
            and np.min(np.linalg.norm(self.unreachable - xy, axis=1)) <= UNREACHABLE_RADIUS
        )

    def advance(self, v: float, w: float, dt: float) -> None:
        """Move for ``dt`` s towards the commanded forward speed ``v`` m/s and turn rate
        ``w`` rad/s (limited by the platform's speeds and accelerations).

        A step into the space's walls, an obstacle or near an unreachable point is not
        taken: the robot stops there and :attr:`stalled` is set (cleared by the next step
        that moves, or a command to stand still).
        """
        if dt <= 0:
            return
        p = self.platform
        v_cmd = max(-self.max_speed, min(self.max_speed, float(v)))
        w_cmd = max(-p.max_yaw_rate, min(p.max_yaw_rate, float(w)))
        if v_cmd == 0.0 and w_cmd == 0.0:
            self.stalled = False
        v0, w0 = self.v, self.w
        self.v = ramp(v0, v_cmd, p.max_accel * dt)
        self.w = ramp(w0, w_cmd, p.max_yaw_accel * dt)
        if not self.moving:
            self.v = self.w = 0.0
            if self._moved:
                self._come_to_rest()
            return
        ds = 0.5 * (v0 + self.v) * dt
        dth = 0.5 * (w0 + self.w) * dt
        mid = self.truth[2] + 0.5 * dth
        step = np.array([ds * math.cos(mid), ds * math.sin(mid)])
        new_xy = self.truth[:2] + step
        if ds != 0.0 and self._blocked(new_xy) and not self._blocked(self.truth[:2]):
            self.stalled = True
            self.v = self.w = 0.0
            if self._moved:
                self._come_to_rest()
            return
        self.stalled = False
        self.truth = np.array([new_xy[0], new_xy[1], _wrap(self.truth[2] + dth)])
        mid_o = self.odometry[2] + 0.5 * dth
        self.odometry = np.array(
            [
                self.odometry[0] + ds * math.cos(mid_o),
                self.odometry[1] + ds * math.sin(mid_o),
                _wrap(self.odometry[2] + dth),
            ]
        )
        self._moved = True
        self._place(settle=0.0)

    def _come_to_rest(self) -> None:
        """The stop: displace the truth by one draw of the stopping error, place it."""
        s = self.stopping
        self.truth[:2] += s.sigma_xy * self.rng.standard_normal(2)
        self.truth[2] = _wrap(self.truth[2] + s.sigma_yaw * self.rng.standard_normal())
        self._moved = False
        self._place(settle=0.1)

    def _place(self, settle: float) -> None:
        with self.lock:
            self.world.place(
                self.name, self.truth[:2], float(self.truth[2]), settle=settle, hold_others=True
            )
