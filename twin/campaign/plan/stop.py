"""A planned stop of a robot."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class Stop:
    """A planned stop of a robot: (x, y) m and heading rad in W."""

    xy: NDArray[np.float64]
    yaw: float
