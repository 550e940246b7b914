"""Wheel odometry that drifts the way real wheel odometry does.

The robot integrates its wheel encoders with its *believed* wheel radius and track width.
Those beliefs are off by a small relative error drawn once per robot (a systematic error,
like a worn tyre or a mis-measured track), and every metre travelled adds random error
(an unsystematic error, like bumps and slip). Skid-steered robots also slip in the
simulation itself, which the odometry cannot see. Together these make dead reckoning drift
without bound: the paper's reason for cooperative positioning.

Pure numpy; the simulator feeds it wheel angle increments.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from calib.rotation import wrap_angle
from twin.scenario.robots import OdometrySpec


class WheelOdometry:
    """Dead reckoning of a differential or skid-steered robot from its wheel angles.

    Args:
        wheel_radius: nominal wheel radius, m.
        track: nominal effective track width, m.
        spec: the error model.
        rng: random generator (the systematic errors are drawn here, once).
        pose: (3,) initial pose estimate (x, y, yaw), m and rad.
    """

    def __init__(
        self,
        wheel_radius: float,
        track: float,
        spec: OdometrySpec,
        rng: np.random.Generator,
        pose: NDArray[np.float64] | tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> None:
        self.spec = spec
        self._rng = rng
        scale = 1.0 + spec.wheel_scale_sigma * rng.standard_normal(2)
        self.radius_left = wheel_radius * float(scale[0])
        self.radius_right = wheel_radius * float(scale[1])
        self.track = track * (1.0 + spec.track_sigma * float(rng.standard_normal()))
        self._pose = np.asarray(pose, dtype=float).reshape(3).copy()
        self.distance = 0.0

    @property
    def pose(self) -> NDArray[np.float64]:
        """(3,) current estimate (x, y, yaw) in the world frame, m and rad."""
        return self._pose.copy()

    def reset(self, pose: NDArray[np.float64] | tuple[float, float, float]) -> None:
        """Set the estimate to ``pose`` (x, y, yaw), e.g. after an external fix."""
        self._pose = np.asarray(pose, dtype=float).reshape(3).copy()

    def update(self, dangle_left: float, dangle_right: float) -> NDArray[np.float64]:
        """Integrate one step of wheel rotation.

        Args:
            dangle_left, dangle_right: wheel angle increments since the last update, rad
                (mean over the wheels of each side).

        Returns:
            (3,) the new pose estimate.
        """
        dl = self.radius_left * dangle_left
        dr = self.radius_right * dangle_right
        ds = 0.5 * (dl + dr)
        dth = (dr - dl) / self.track
        travelled = abs(ds) + 0.5 * abs(dth) * self.track
        if travelled > 0.0:
            root = np.sqrt(travelled)
            noise = self._rng.standard_normal(2)
            ds += self.spec.distance_noise * root * float(noise[0])
            dth += self.spec.heading_noise * root * float(noise[1])
        x, y, th = self._pose
        mid = th + 0.5 * dth
        self._pose = np.array(
            [x + ds * np.cos(mid), y + ds * np.sin(mid), float(wrap_angle(th + dth))]
        )
        self.distance += abs(ds)
        return self._pose.copy()
