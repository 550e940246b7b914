"""Go-to-pose controller for the Pioneers: turn, drive, turn, stop, within their limits.

The controller turns a pose estimate into body velocity commands (v forward, w yaw rate),
with the speed and acceleration limits of :class:`twin.scenario.robots.Platform`:

1. turn in place towards the goal while the bearing error exceeds ``turn_first`` (inside
   ``slow_radius``, where the robot no longer steers, until it points at the goal well
   enough to pass within half the position tolerance; there it may face away from a goal
   behind it and reverse onto it instead);
2. drive forward (or back, near the goal), steering onto the bearing, at a speed that can
   still stop at the goal with the acceleration limit (v <= sqrt(2 a d)); a goal left
   beside the robot sends it back to step 1;
3. brake at the acceleration limit so as to stop at the goal, and turn in place to the
   goal heading (if one is given);
4. report done once stopped within the position tolerance of the goal, heading within
   tolerance; stopped off the goal, start again at step 1.

Pure Python; :class:`twin.sim.world.World` feeds it poses and applies its commands.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

from calib.rotation import wrap_angle
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
        self.tolerance = tolerance or DriveTolerance()
        self.phase = DrivePhase.TURN_TO_GOAL
        self.v = 0.0
        self.w = 0.0
        self.direction = 1.0  # +1 driving forwards, -1 reversing (near the goal only)

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
            if dist <= self.tolerance.position:
                self.phase = DrivePhase.TURN_TO_HEADING
            else:
                err = self._aim(dx, dy, dist, yaw)
                if abs(err) <= self._aim_tolerance(dist):
                    self.phase = DrivePhase.DRIVE
                else:
                    w_t = self._turn_rate(err)
        if self.phase is DrivePhase.DRIVE:
            # v <= sqrt(2 a d) has braked the robot on the way in; what speed is left at
            # the goal (about sqrt(2 a tol)) ramps down in the next phase.
            ahead = self.direction * along
            if dist <= self.tolerance.position:
                self.phase = DrivePhase.TURN_TO_HEADING
            elif ahead <= 0.0:
                # Level with the goal but not on it (it lies beside the robot): aim again.
                self.phase = DrivePhase.TURN_TO_GOAL
                w_t = self._turn_rate(self._aim(dx, dy, dist, yaw))
            else:
                err = wrap_angle(math.atan2(dy, dx) - yaw)
                if dist > self.tolerance.slow_radius and abs(err) > 2.0 * self.tolerance.turn_first:
                    self.phase = DrivePhase.TURN_TO_GOAL
                    w_t = self._turn_rate(self._aim(dx, dy, dist, yaw))
                else:
                    v_t = min(p.max_speed, math.sqrt(2.0 * p.max_accel * ahead))
                    v_t = self.direction * max(v_t, 0.02)
                    if dist > self.tolerance.slow_radius:
                        w_t = max(-p.max_yaw_rate, min(p.max_yaw_rate, 2.0 * err))
        settled = False
        if self.phase is DrivePhase.TURN_TO_HEADING:
            err = 0.0 if self.goal_yaw is None else wrap_angle(self.goal_yaw - yaw)
            if abs(err) <= self.tolerance.heading:
                settled = True
            elif self.v == 0.0:  # turn in place only once stopped, so as not to drift
                w_t = self._turn_rate(err)
        if self.phase is DrivePhase.DONE:
            v_t, w_t = 0.0, 0.0
        self.v = ramp(self.v, v_t, p.max_accel * dt)
        self.w = ramp(self.w, w_t, p.max_yaw_accel * dt)
        if settled and self.v == 0.0 and self.w == 0.0:
            # Done only on the goal: a robot that stopped off it (braking overshoot, a turn
            # in place that shifted it) closes the gap again.
            done = dist <= self.tolerance.position
            self.phase = DrivePhase.DONE if done else DrivePhase.TURN_TO_GOAL
        return self.v, self.w

    def _aim(self, dx: float, dy: float, dist: float, yaw: float) -> float:
        """Heading error towards the goal, rad; sets :attr:`direction`.

        Far from the goal the robot drives forwards. Inside ``slow_radius`` it may reverse
        instead, whichever needs the smaller turn (a goal a few cm behind is backed onto).
        """
        err = wrap_angle(math.atan2(dy, dx) - yaw)
        self.direction = 1.0
        if dist < self.tolerance.slow_radius and abs(err) > 0.5 * math.pi:
            self.direction = -1.0
            err = wrap_angle(err - math.pi)
        return err

    def _aim_tolerance(self, dist: float) -> float:
        """Heading error allowed before driving off towards a goal ``dist`` away, rad.

        Inside ``slow_radius`` the robot no longer steers, so it must point well enough to
        pass within half the position tolerance of the goal.
        """
        if dist >= self.tolerance.slow_radius:
            return self.tolerance.turn_first
        tol = self.tolerance
        return min(tol.turn_first, math.asin(min(1.0, 0.5 * tol.position / dist)))

    def _turn_rate(self, err: float) -> float:
        p = self.platform
        rate = min(p.max_yaw_rate, math.sqrt(2.0 * p.max_yaw_accel * abs(err)))
        rate = max(rate, math.radians(3.0))
        return math.copysign(rate, err)


def ramp(current: float, target: float, step: float) -> float:
    """``current`` moved towards ``target`` by at most ``step`` (a speed under a limited
    acceleration, the units of the three)."""
    if target > current:
        return min(target, current + step)
    return max(target, current - step)
