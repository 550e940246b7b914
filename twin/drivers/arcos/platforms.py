"""The Pioneer 3 platforms under ARCOS: the conversion factors from the protocol's units
(positions, headings, wheel velocities) into SI.

Written from the robots' published parameter files (ARIA's ``params/p3dx-sh.p`` and
``params/p3at-sh.p``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class PlatformParams:
    """Conversion factors of one Pioneer model with the ARCOS (SH) controller: the values
    of ARIA's ``p3dx-sh.p`` / ``p3at-sh.p`` parameter files.

    Attributes:
        model: ``p3dx`` or ``p3at``.
        subtype: the subtype an ARCOS robot reports in its SYNC2 answer, ``p3dx-sh`` /
            ``p3at-sh`` (a bare ``p3dx`` / ``p3at`` is the older H8 controller, whose
            DistConvFactor is 0.485 / 0.465 mm per unit: the driver refuses it).
        dist_conv: DistConvFactor, mm per position unit (XPOS, YPOS).
        vel_conv: VelConvFactor, mm/s per wheel-velocity unit.
        angle_conv: AngleConvFactor, rad per heading unit (THPOS, CONTROL): 2 pi / 4096
            (the parameter files round it to 0.001534).
        diff_conv: DiffConvFactor, the turn rate per wheel speed: rad/s per mm/s of
            (right - left) / 2, i.e. 2 / (effective track, mm). Firmware that sends ROTVEL
            makes it unnecessary.
        vel2_divisor: Vel2Divisor, mm/s per unit of the VEL2 command.
    """

    model: str
    subtype: str
    dist_conv: float
    vel_conv: float
    angle_conv: float
    diff_conv: float
    vel2_divisor: float = 20.0

    def position_m(self, units: int | float) -> float:
        """Position units -> m."""
        return float(units) * self.dist_conv / 1000.0

    def position_units(self, metres: float) -> int:
        """m -> position units, rounded, modulo 15 bits."""
        return round(metres * 1000.0 / self.dist_conv) & 0x7FFF

    def heading_rad(self, units: int) -> float:
        """Heading units -> rad in (-pi, pi]."""
        a = float(units) * self.angle_conv
        wrapped = math.atan2(math.sin(a), math.cos(a))
        return math.pi if wrapped <= -math.pi else wrapped  # -pi itself is pi

    def heading_units(self, rad: float) -> int:
        """rad -> heading units, the angle wrapped to [-pi, pi)."""
        a = (rad + math.pi) % (2 * math.pi) - math.pi
        return round(a / self.angle_conv)

    def wheel_units(self, mps: float) -> int:
        """m/s -> wheel-velocity units, rounded."""
        return round(mps * 1000.0 / self.vel_conv)


ANGLE_UNIT = 2.0 * math.pi / 4096.0
"""Radians per heading unit: ARCOS reports headings in 4096ths of a turn."""

PLATFORMS: dict[str, PlatformParams] = {
    "p3dx": PlatformParams(
        model="p3dx",
        subtype="p3dx-sh",
        dist_conv=1.0,
        vel_conv=1.0,
        angle_conv=ANGLE_UNIT,
        diff_conv=0.0056,
    ),
    "p3at": PlatformParams(
        model="p3at",
        subtype="p3at-sh",
        dist_conv=1.0,
        vel_conv=1.0,
        angle_conv=ANGLE_UNIT,
        diff_conv=0.0034,
    ),
}
"""The Pioneer 3-DX and 3-AT under ARCOS: positions in mm, velocities in mm/s, headings in
4096ths of a turn, Vel2Divisor 20; DiffConvFactor 0.0056 (DX) and 0.0034 (AT, skid
steering)."""


def platform(model: str) -> PlatformParams:
    """The parameters of ``model`` (``p3dx`` or ``p3at``).

    Raises:
        ValueError: another model.
    """
    try:
        return PLATFORMS[model.lower()]
    except KeyError:
        raise ValueError(f"model must be one of {sorted(PLATFORMS)}, got {model!r}") from None
