"""A planned stop of a robot."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class Stop:
    """A planned stop of a robot: (x, y) m and heading rad in W; for a child's stop in a
    camera's view, ``leds``: the indices of the LEDs the camera is planned to see there
    (None: all of them)."""

    xy: NDArray[np.float64]
    yaw: float
    leds: tuple[int, ...] | None = None
