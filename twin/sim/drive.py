"""Go-to-pose controller for the Pioneers: turn, drive, turn, stop, within their limits.

The controller turns a pose estimate into body velocity commands (v forward, w yaw rate),
with the speed and acceleration limits of :class:`twin.scenario.robots.Platform`:

1. turn in place towards the goal while the bearing error exceeds ``turn_first``;
2. drive forward, steering onto the bearing, at a speed that can still stop at the goal
   with the acceleration limit (v <= sqrt(2 a d));
3. brake at the acceleration limit so as to stop at the goal, and turn in place to the
   goal heading (if one is given);
4. report done once the heading is within tolerance and the commands have ramped to zero.

Pure Python; :class:`twin.sim.scene.World` feeds it poses and applies its commands.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

from twin.scenario.robots import Platform


class DrivePhase(Enum):
    """Where the controller is in its sequence."""

    TURN_TO_GOAL = "turn_to_goal"
    DRIVE = "drive"
    TURN_TO_HEADING = "turn_to_heading"
    DONE = "done"


@dataclass(frozen=True)
class DriveTolerance:
    """When a goal counts as reached.

    Attributes:
        position: m. heading: rad. turn_first: bearing error above which the robot turns
        in place before driving, rad. slow_radius: inside this distance the robot stops
        steering and only closes the distance along its heading, m.
    """

    position: float = 0.01
    heading: float = math.radians(0.5)
    turn_first: float = math.radians(15.0)
    slow_radius: float = 0.10


def wrap(angle: float) -> float:
    """Angle wrapped to [-pi, pi), rad."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


class DriveController:
    """Drives one robot to a goal pose.

    Args:
        platform: the robot's limits.
        goal_xy: (x, y) goal of the body origin, m.
        goal_yaw: goal heading, rad, or None to keep the arrival heading.
        tolerance: when the goal counts as reached.
    """

    def __init__(
        self,
        platform: Platform,
        goal_xy: tuple[float, float],
        goal_yaw: float | None = None,
        tolerance: DriveTolerance | None = None,
    ) -> None:
        self.platform = platform
        self.goal_xy = (float(goal_xy[0]), float(goal_xy[1]))
        self.goal_yaw = None if goal_yaw is None else float(goal_yaw)
        self.tol = tolerance or DriveTolerance()
        self.phase = DrivePhase.TURN_TO_GOAL
        self.v = 0.0
        self.w = 0.0

    @property
    def done(self) -> bool:
        """Whether the goal has been reached and zero is commanded."""
        return self.phase is DrivePhase.DONE

    def update(self, pose: tuple[float, float, float], dt: float) -> tuple[float, float]:
        """One control step.

        Args:
            pose: (x, y, yaw) estimate of the robot, m and rad.
            dt: time since the last update, s.

        Returns:
            (v, w): forward speed (m/s) and yaw rate (rad/s) to command.
        """
        p = self.platform
        x, y, yaw = pose
        dx, dy = self.goal_xy[0] - x, self.goal_xy[1] - y
        dist = math.hypot(dx, dy)
        along = dx * math.cos(yaw) + dy * math.sin(yaw)
        v_t, w_t = 0.0, 0.0
        if self.phase is DrivePhase.TURN_TO_GOAL:
            if dist <= self.tol.position:
                self.phase = DrivePhase.TURN_TO_HEADING
            else:
                err = wrap(math.atan2(dy, dx) - yaw)
                if abs(err) <= self.tol.turn_first or dist < self.tol.slow_radius:
                    self.phase = DrivePhase.DRIVE
                else:
                    w_t = self._turn_rate(err)
        if self.phase is DrivePhase.DRIVE:
            # v <= sqrt(2 a d) has braked the robot on the way in; what speed is left at
            # the goal (about sqrt(2 a tol)) ramps down in the next phase.
            if dist <= self.tol.position or along <= 0.0:
                self.phase = DrivePhase.TURN_TO_HEADING
            else:
                err = wrap(math.atan2(dy, dx) - yaw)
                if dist > self.tol.slow_radius and abs(err) > 2.0 * self.tol.turn_first:
                    self.phase = DrivePhase.TURN_TO_GOAL
                    w_t = self._turn_rate(err)
                else:
                    v_t = min(p.max_speed, math.sqrt(2.0 * p.max_accel * along))
                    v_t = max(v_t, 0.02)
                    if dist > self.tol.slow_radius:
                        w_t = max(-p.max_yaw_rate, min(p.max_yaw_rate, 2.0 * err))
        settled = False
        if self.phase is DrivePhase.TURN_TO_HEADING:
            err = 0.0 if self.goal_yaw is None else wrap(self.goal_yaw - yaw)
            if abs(err) <= self.tol.heading:
                settled = True
            elif self.v == 0.0:  # turn in place only once stopped, so as not to drift
                w_t = self._turn_rate(err)
        if self.phase is DrivePhase.DONE:
            v_t, w_t = 0.0, 0.0
        self.v = _ramp(self.v, v_t, p.max_accel * dt)
        self.w = _ramp(self.w, w_t, p.max_yaw_accel * dt)
        if settled and self.v == 0.0 and self.w == 0.0:
            self.phase = DrivePhase.DONE
        return self.v, self.w

    def _turn_rate(self, err: float) -> float:
        p = self.platform
        rate = min(p.max_yaw_rate, math.sqrt(2.0 * p.max_yaw_accel * abs(err)))
        rate = max(rate, math.radians(3.0))
        return math.copysign(rate, err)


def _ramp(current: float, target: float, step: float) -> float:
    if target > current:
        return min(target, current + step)
    return max(target, current - step)
