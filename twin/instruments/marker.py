"""The LED and corner-cube assembly carried by a child robot (the paper's Fig. 7).

Default geometry (body frame: origin on the floor below the robot's centre, x forward,
z up; metres): three corner cubes on a horizontal triangle with sides 0.29, 0.33 and
0.34 m at 1.40 m on top of the mast, and four LEDs on short stubs 3.5 cm in front of the
mast between 0.35 m and 1.25 m, so the LEDs span 0.9 m in height on one vertical line. The
cube triangle fits on a Pioneer 3-DX (0.44 x 0.38 m), is far from collinear (a
well-conditioned pose), and its centroid lies on the mast's axis, so an error in the
assembly's heading moves the LEDs only by their 3.5 cm lever arm; the pose error that does
reach the LEDs is the tilt of the triangle times the lever arm down the mast.

The LEDs stand in front of the mast so that a camera facing the robot's front sees each
one whole: an LED threaded on the mast's axis has the mast rising out of its top, and a
camera looking down (all of them do) sees the mast cover the LED's upper edge, which moves
the centroid of its image down by 0.2-0.6 px at 3-5 m. Seen from behind, the mast can hide
the LEDs: the child turns its front to the camera it is working for.

The triangle is deliberately scalene (sides differing by 1-5 cm): with an isosceles
triangle two cubes can be swapped by a rigid motion, so a wrong prism lock would fit with
zero residual. Here every wrong labelling of the cubes leaves a residual of at least 1 cm
rms (:attr:`MarkerPose.rms_residual`), well above the millimetre noise.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray


def _default_cubes() -> NDArray[np.float64]:
    # Three corner cubes on a scalene horizontal triangle on top of the mast, body frame, m.
    return np.array([[0.18, 0.0, 1.40], [-0.12, 0.16, 1.40], [-0.06, -0.16, 1.40]])


def _default_leds() -> NDArray[np.float64]:
    # Four LEDs in front of the mast at different heights above the floor, body frame, m.
    return np.array(
        [[0.035, 0.0, 0.35], [0.035, 0.0, 0.65], [0.035, 0.0, 0.95], [0.035, 0.0, 1.25]]
    )


@dataclass(frozen=True, eq=False)
class MarkerAssembly:
    """Fixed geometry of the marker assembly in the child robot's body frame.

    The body frame has its origin on the floor below the robot's centre, x forward, z up.

    Attributes:
        cubes_body: (3, 3) corner-cube (prism) reflection points, m.
        leds_body: (4, 3) LED centres, m.
        survey_sigma: how well this geometry is known: standard deviation of each
            coordinate of each cube and LED, m (default 0: exactly). The marker fit's
            consistency test allows for it; the pose and LED covariances do not (it is a
            fixed error of each built assembly, not noise of the shots).
    """

    cubes_body: NDArray[np.float64] = field(default_factory=_default_cubes)
    leds_body: NDArray[np.float64] = field(default_factory=_default_leds)
    survey_sigma: float = 0.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.survey_sigma) and self.survey_sigma >= 0):
            raise ValueError(
                f"survey_sigma must be finite and non-negative (m), got {self.survey_sigma}"
            )
        cubes = np.array(self.cubes_body, dtype=float)
        leds = np.array(self.leds_body, dtype=float)
        if cubes.shape != (3, 3):
            raise ValueError(f"cubes_body must have shape (3, 3), got {cubes.shape}")
        if leds.ndim != 2 or leds.shape[1] != 3 or leds.shape[0] == 0:
            raise ValueError(f"leds_body must have shape (N, 3), got {leds.shape}")
        if not (np.all(np.isfinite(cubes)) and np.all(np.isfinite(leds))):
            raise ValueError("cubes_body and leds_body must be finite")
        sides = np.linalg.norm(np.roll(cubes, 1, axis=0) - cubes, axis=1)
        area2 = np.linalg.norm(np.cross(cubes[1] - cubes[0], cubes[2] - cubes[0]))
        if area2 < 1e-3 * sides.max() ** 2:
            raise ValueError(
                f"the three corner cubes are (nearly) collinear (twice the triangle area "
                f"{area2:.3g} m^2, longest side {sides.max():.3g} m); the assembly's pose "
                "would be undetermined"
            )
        cubes.setflags(write=False)
        leds.setflags(write=False)
        object.__setattr__(self, "cubes_body", cubes)
        object.__setattr__(self, "leds_body", leds)

    @property
    def reference_body(self) -> NDArray[np.float64]:
        """(3,) the assembly's reference point: the centroid of the three cubes, body, m.

        CPS positions a child by this point: it is the mean of the three measured cubes,
        whatever the child's heading.
        """
        return self.cubes_body.mean(axis=0)
