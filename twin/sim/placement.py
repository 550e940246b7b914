"""Where to stand a child robot so that one of its LEDs appears where a test wants it.

Pure geometry on the camera model and the marker assembly: the LED at a given height above
the floor, a given distance from the camera, on a given image column. Used to sample LED
positions over a camera's view at chosen distances (detection tests and benchmarks).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from calib.camera import TsaiCamera
from calib.opencv_camera import OpenCVCamera


def stand_for_led(
    camera: TsaiCamera | OpenCVCamera,
    led_body: NDArray[np.float64],
    floor_z: float,
    distance: float,
    u: float,
) -> tuple[NDArray[np.float64], float] | None:
    """A child's floor pose that puts one LED at ``distance`` from the camera on column ``u``.

    The child faces the camera (its LEDs stand in front of its mast).

    Args:
        camera: the camera.
        led_body: (3,) the LED's position in the child's body frame, m.
        floor_z: the floor's height in the world frame, m.
        distance: wanted distance from the optical centre to the LED, m.
        u: wanted image column of the LED, px.

    Returns:
        ((2,) body origin on the floor, m; yaw, rad), or None when no row of that column
        sees the LED's height at that distance.
    """
    led = np.asarray(led_body, dtype=float).reshape(3)
    z = floor_z + led[2]
    o = camera.position
    # Each row's line of sight reaches height z after (z - o_z) / d_z metres.
    h = camera.image_size[1]
    rows = np.linspace(-0.5, h - 0.5, 4 * h + 1)
    _, d = camera.unproject(np.column_stack([np.full_like(rows, u), rows]))
    with np.errstate(divide="ignore", invalid="ignore"):
        reach = (z - o[2]) / d[:, 2]
    ok = np.isfinite(reach) & (reach > 0)
    if not ok.any() or not (reach[ok].min() <= distance <= reach[ok].max()):
        return None
    i = int(np.argmin(np.where(ok, np.abs(reach - distance), np.inf)))
    p = o + reach[i] * d[i]
    yaw = math.atan2(o[1] - p[1], o[0] - p[0])
    c, s = math.cos(yaw), math.sin(yaw)
    offset = np.array([c * led[0] - s * led[1], s * led[0] + c * led[1]])
    return p[:2] - offset, yaw
