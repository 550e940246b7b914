"""The LED and corner-cube assembly carried by a child robot (the paper's Fig. 7)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray


def _default_cubes() -> NDArray[np.float64]:
    # Three corner cubes on a horizontal triangle on top of the mast, body frame, m.
    return np.array([[0.15, 0.0, 1.40], [-0.10, 0.15, 1.40], [-0.10, -0.15, 1.40]])


def _default_leds() -> NDArray[np.float64]:
    # Four LEDs on the mast at different heights above the floor, body frame, m.
    return np.array([[0.0, 0.0, 0.35], [0.0, 0.0, 0.65], [0.0, 0.0, 0.95], [0.0, 0.0, 1.25]])


@dataclass(frozen=True, eq=False)
class MarkerAssembly:
    """Fixed geometry of the marker assembly in the child robot's body frame.

    The body frame has its origin on the floor below the robot's centre, x forward, z up.

    Attributes:
        cubes_body: (3, 3) corner-cube (prism) reflection points, m.
        leds_body: (4, 3) LED centres, m.
    """

    cubes_body: NDArray[np.float64] = field(default_factory=_default_cubes)
    leds_body: NDArray[np.float64] = field(default_factory=_default_leds)
