"""A Pioneer base driven over ARCOS: :class:`twin.hal.MobileBase` on a
:class:`~twin.drivers.arcos.connection.PioneerConnection`.

ARCOS reports odometry in its own frame (zero where the session opened) and cannot be told
an arbitrary pose, so the base keeps an anchor on the host: a pose in W and the ARCOS pose
that had it. ``W pose = anchor_w (x) (anchor_odo^-1 (x) ARCOS pose)``, the relative motion
computed so that an unchanged ARCOS pose reads back the anchor exactly. The anchor starts
where the robot stood in W when the connection opened and is moved by
:meth:`ArcosBase.set_pose`. Drives are a go-to-pose controller on the host, one velocity
command (VEL mm/s, RVEL deg/s) per SIP.
"""

from __future__ import annotations

import contextlib
import math

import numpy as np
from numpy.typing import ArrayLike

from calib.rotation import compose_planar, invert_planar
from twin.drivers.arcos.connection import ArcosPose, PioneerConnection
from twin.drivers.arcos.protocol import Command
from twin.hal.devices import MobileBase
from twin.hal.errors import DeviceLostError
from twin.hal.readings import DriveResult, DriveStatus, OdometryReading

DECELERATION = 0.2
"""Deceleration the controller plans its approach with, m/s^2 (below either Pioneer's)."""

TURN_DECELERATION = 0.6
"""Angular deceleration the controller plans its turns with, rad/s^2."""

MIN_SPEED = 0.02
"""Slowest forward speed the controller asks for short of the goal, m/s."""

MIN_TURN_RATE = math.radians(2.0)
"""Slowest turn rate it asks for short of a heading (RVEL's unit is 1 deg/s), rad/s."""

AIM_ANGLE = 0.3
"""Heading error beyond which the base turns on the spot before driving on, rad."""

STOP_WAIT = 5.0
"""Rig seconds a drive waits for the robot to report it has stopped, s."""


def _relative(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a^-1 (x) b, exactly (0, 0, 0) when b equals a."""
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    return np.array([c * dx + s * dy, -s * dx + c * dy, b[2] - a[2]])


def _wrap(angle: float) -> float:
    """The angle in (-pi, pi]; one already there is returned unchanged."""
    if -math.pi < angle <= math.pi:
        return float(angle)
    return math.atan2(math.sin(angle), math.cos(angle))


class ArcosBase(MobileBase):
    """A Pioneer 3 base over ARCOS.

    Args:
        connection: the open session (the base closes it).
        name: the robot's name.
        start_pose: (x m, y m, yaw rad) of the robot in W when the connection opened.
        max_speed: forward speed limit of the drives, m/s.
        max_turn_rate: turn-rate limit, rad/s.
        goal_tolerance: a drive stops within this distance of its goal, m.
        yaw_tolerance: and within this heading of ``goal_yaw``, rad.
        drive_timeout_s: rig seconds after which a drive gives up (TIMEOUT).
    """

    def __init__(
        self,
        connection: PioneerConnection,
        *,
        name: str,
        start_pose: tuple[float, float, float],
        max_speed: float,
        max_turn_rate: float,
        goal_tolerance: float = 0.02,
        yaw_tolerance: float = 0.01,
        drive_timeout_s: float = 120.0,
    ) -> None:
        for label, value in (
            ("max_speed", max_speed),
            ("max_turn_rate", max_turn_rate),
            ("goal_tolerance", goal_tolerance),
            ("yaw_tolerance", yaw_tolerance),
            ("drive_timeout_s", drive_timeout_s),
        ):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{label} must be a positive number, got {value!r}")
        start = np.asarray(start_pose, dtype=float).reshape(3)
        if not np.all(np.isfinite(start)):
            raise ValueError(f"start_pose must be a finite (x, y, yaw), got {start_pose!r}")
        self.connection = connection
        self.clock = connection.clock
        self._name = name
        self.max_speed = float(max_speed)
        self.max_turn_rate = float(max_turn_rate)
        self.goal_tolerance = float(goal_tolerance)
        self.yaw_tolerance = float(yaw_tolerance)
        self.drive_timeout_s = float(drive_timeout_s)
        self._closed = False
        self._anchor_w = start
        self._anchor_odo = connection.pose().pose

    @property
    def _odo2w(self) -> np.ndarray:
        """The ARCOS-to-W transform the anchor makes."""
        return compose_planar(self._anchor_w, invert_planar(self._anchor_odo))

    @property
    def name(self) -> str:
        return self._name

    # -- localisation ---------------------------------------------------------------------------
    def _to_w(self, pose: ArcosPose) -> np.ndarray:
        return compose_planar(self._anchor_w, _relative(self._anchor_odo, pose.pose))

    def _reading(self, pose: ArcosPose) -> OdometryReading:
        w = self._to_w(pose)
        now = self.clock.now()  # the reading is the robot's belief now (its newest SIP)
        return OdometryReading(self._name, now, float(w[0]), float(w[1]), _wrap(w[2]))

    def odometry(self) -> OdometryReading:
        """The pose in W of the newest SIP.

        Raises:
            DeviceLostError: the link failed or the robot fell silent.
        """
        return self._reading(self.connection.pose())

    def set_pose(self, x: float, y: float, yaw: float) -> None:
        """Re-anchor the ARCOS-to-W transform so that the newest odometry reads (x, y, yaw).

        Raises:
            ValueError: the pose is not finite.
            DeviceLostError: the link failed or the robot fell silent.
        """
        if not all(math.isfinite(v) for v in (x, y, yaw)):
            raise ValueError(f"a pose fix must be finite, got x={x}, y={y}, yaw={yaw}")
        pose = self.connection.pose()
        self._anchor_w = np.array([x, y, yaw], dtype=float)
        self._anchor_odo = pose.pose

    # -- driving ---------------------------------------------------------------------------
    def _command(self, v: float, w: float) -> None:
        conn = self.connection
        conn.send(Command.VEL, round(v * 1000.0))
        conn.send(Command.RVEL, round(math.degrees(w)))

    def _stop(self) -> None:
        self._command(0.0, 0.0)

    def _wait_stopped(self) -> None:
        """Wait until a SIP says the motors stopped (type 0x32; or the e-stop is engaged)."""
        with contextlib.suppress(DeviceLostError):
            self.connection.wait_for(lambda s: not s.moving or s.estop, STOP_WAIT)
        self.connection.latest()  # raises if the robot was lost meanwhile

    def _speed(self, distance: float) -> float:
        v = min(self.max_speed, math.sqrt(2.0 * DECELERATION * distance), 1.5 * distance)
        return max(v, MIN_SPEED)

    def _turn(self, error: float) -> float:
        a = abs(error)
        w = min(self.max_turn_rate, math.sqrt(2.0 * TURN_DECELERATION * a), 2.0 * a)
        return math.copysign(max(w, MIN_TURN_RATE), error)

    def _control(
        self, here: np.ndarray, goal: np.ndarray, goal_yaw: float | None
    ) -> tuple[float, float] | None:
        """(v m/s, w rad/s) towards the goal (odometry frame), or None when there."""
        dx, dy = goal[0] - here[0], goal[1] - here[1]
        distance = math.hypot(dx, dy)
        if distance > self.goal_tolerance:
            error = _wrap(math.atan2(dy, dx) - here[2])
            sign = 1.0
            if distance < 0.2 and abs(error) > 0.5 * math.pi:
                error, sign = _wrap(error + math.pi), -1.0  # just past it: back up
            if abs(error) > AIM_ANGLE:
                return 0.0, self._turn(error)
            v = sign * self._speed(distance) * math.cos(error)
            w = max(-self.max_turn_rate, min(self.max_turn_rate, 1.5 * error))
            if distance < 0.1:
                w = 0.0  # close in, the bearing is noise: roll straight
            return v, w
        if goal_yaw is None:
            return None
        error = _wrap(goal_yaw - here[2])
        if abs(error) <= self.yaw_tolerance:
            return None
        return 0.0, self._turn(error)

    def drive_to(self, goal_xy: ArrayLike, goal_yaw: float | None = None) -> DriveResult:
        """Drive to (x, y) m in W, turn to ``goal_yaw`` rad if given, stop; block until
        stopped.

        Ends BLOCKED (``stalled``, ``e-stop``, ``motors disabled``) when a SIP reports a
        stall, the emergency stop or the motors off, TIMEOUT after ``drive_timeout_s``; the
        robot is stopped either way. A goal that is not finite ends BLOCKED at once, the
        robot not moved.

        Raises:
            DeviceLostError: the link failed or the robot fell silent (a stop was tried).
            Anything else the loop raises (an interrupt, a bug) also stops the robot first:
            the keep-alive PULSEs would otherwise keep it driving at its last command.
        """
        g = np.asarray(goal_xy, dtype=float).reshape(2)
        goal_w = np.array([g[0], g[1], np.nan if goal_yaw is None else float(goal_yaw)])
        start = self.clock.now()
        if not np.all(np.isfinite(g)) or (goal_yaw is not None and not math.isfinite(goal_yaw)):
            return DriveResult(
                robot=self._name,
                timestamp=start,
                goal=goal_w,
                status=DriveStatus.BLOCKED,
                odometry=self.odometry(),
                duration=0.0,
                message=f"the goal must be finite, got ({g[0]}, {g[1]}) yaw {goal_yaw}",
            )
        w2odo = invert_planar(self._odo2w)
        local = compose_planar(w2odo, np.array([g[0], g[1], 0.0 if goal_yaw is None else goal_yaw]))
        local_yaw = None if goal_yaw is None else float(local[2])
        status, message = DriveStatus.REACHED, ""
        try:
            seen = self.connection.sip_count
            while True:
                sip = self.connection.wait_for(lambda s: True, after=seen)
                seen = self.connection.sip_count
                if sip.estop:
                    status, message = DriveStatus.BLOCKED, "e-stop"
                    break
                if sip.stalled:
                    status, message = DriveStatus.BLOCKED, "stalled"
                    break
                if not sip.motors_enabled:
                    status, message = DriveStatus.BLOCKED, "motors disabled"
                    break
                elapsed = self.clock.now() - start
                if elapsed > self.drive_timeout_s:
                    status = DriveStatus.TIMEOUT
                    message = f"not at the goal after {elapsed:.1f} s"
                    break
                command = self._control(self.connection.pose().pose, local, local_yaw)
                if command is None:
                    break
                self._command(*command)
            self._stop()
            self._wait_stopped()
        except BaseException:
            with contextlib.suppress(Exception):
                self._stop()
            raise
        now = self.clock.now()
        return DriveResult(
            robot=self._name,
            timestamp=now,
            goal=goal_w,
            status=status,
            odometry=self.odometry(),
            duration=now - start,
            message=message,
        )

    def close(self) -> None:
        """Stop the robot, CLOSE the session, close the port. Twice is harmless."""
        if self._closed:
            return
        self._closed = True
        self.connection.close()
