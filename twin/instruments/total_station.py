"""Total station (Topcon GTS-820A) measurement model."""

from __future__ import annotations

from dataclasses import dataclass

ARCSEC = 3.141592653589793 / (180.0 * 3600.0)


@dataclass(frozen=True)
class TotalStationSpec:
    """Noise, resolution and range of a total station; defaults from the paper's Table I.

    Attributes:
        distance_sigma_const: constant part of the distance standard deviation, m.
        distance_sigma_ppm: distance-proportional part, parts per million of the distance.
        angle_sigma: standard deviation of each angle (horizontal and zenith), rad.
        distance_resolution: output resolution of the distance, m.
        angle_resolution: output resolution of the angles, rad.
        range_min, range_max: measurable slope distances, m.
        aim_cone: half-angle of the automatic aim's search cone, rad.
    """

    distance_sigma_const: float = 2e-3
    distance_sigma_ppm: float = 2.0
    angle_sigma: float = 5.0 * ARCSEC
    distance_resolution: float = 0.2e-3
    angle_resolution: float = 1.0 * ARCSEC
    range_min: float = 1.3
    range_max: float = 2200.0
    aim_cone: float = 5.0 * 3.141592653589793 / 180.0


@dataclass(frozen=True)
class InclinometerSpec:
    """Two-axis inclination sensor of the parent robot.

    Attributes:
        sigma: standard deviation of each tilt axis, rad (default 1 arc-second).
        working_range: largest tilt the compensator accepts, rad (default 3 arc-minutes).
    """

    sigma: float = 1.0 * ARCSEC
    working_range: float = 180.0 * ARCSEC
