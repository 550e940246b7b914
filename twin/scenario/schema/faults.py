"""``[faults]``: faults injected into the simulated devices."""

from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import Field

from calib.camera import TsaiCamera
from calib.pose_change import moved_camera
from twin.scenario.limits import MAX_CAMERAS, MAX_WAYPOINTS, Point2, Point3
from twin.scenario.schema.frozen import Frozen, Name

TurnDeg = Annotated[float, Field(ge=-180.0, le=180.0)]
"""A component of a rotation vector, degrees: half a turn either way."""


class MovedCamera(Frozen):
    """A camera that was knocked or re-mounted after its calibration: the twin's world
    holds it at this pose (``[[faults.moved_cameras]]``), the scenario's ``[[cameras]]``
    entry keeps the pose it had.

    The convention is :mod:`calib.pose_change`'s: the optical centre moves by ``shift``
    in the world frame, then the camera turns by the rotation vector ``turn_deg`` given in
    its own axes (x right, y down, z forward: for small turns, tilt, pan and roll).

    Attributes:
        camera: the camera's name (one of ``[[cameras]]``).
        shift: (dx, dy, dz) of the optical centre in the world frame, m.
        turn_deg: rotation vector about the camera's own x, y, z axes, degrees.
    """

    camera: Name
    shift: Point3 = (0.0, 0.0, 0.0)
    turn_deg: tuple[TurnDeg, TurnDeg, TurnDeg] = (0.0, 0.0, 0.0)

    def moved(self, camera: TsaiCamera) -> TsaiCamera:
        """``camera`` (the scenario's pose) at this fault's pose."""
        moved = moved_camera(camera, self.shift, np.radians(self.turn_deg))
        assert isinstance(moved, TsaiCamera)
        return moved


class Faults(Frozen):
    """Faults injected into the simulated devices, to see a run cope with them.

    Attributes:
        lost_lock_rate: probability that the total station's automatic aim fails to lock
            a prism it could see (the shot fails as if no prism were in the cone).
        hidden_led_rate: probability that an LED stays dark during one observation (as if
            something hid it from the camera).
        unreachable: (x, y) goals, m, that no robot can reach: a drive to within 0.5 m of
            one stops short, blocked (at most ``MAX_WAYPOINTS``).
        moved_cameras: cameras the twin's world holds away from their scenario pose (at
            most one entry per camera; see :class:`MovedCamera`).
    """

    lost_lock_rate: Annotated[float, Field(ge=0.0, le=1.0)] = 0.0
    hidden_led_rate: Annotated[float, Field(ge=0.0, le=1.0)] = 0.0
    unreachable: tuple[Point2, ...] = Field(default=(), max_length=MAX_WAYPOINTS)
    moved_cameras: tuple[MovedCamera, ...] = Field(default=(), max_length=MAX_CAMERAS)

    def moved_camera(self, name: str) -> MovedCamera | None:
        """The fault that moves camera ``name``, or None."""
        return next((m for m in self.moved_cameras if m.camera == name), None)
