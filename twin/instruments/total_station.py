"""Total station (Topcon GTS-820A) specification: noise, resolution, range, aim, tilt.

The defaults are the paper's Table I. The precision "+/-(2 mm + 2 ppm x D)" and "5 sec"
are read as one standard deviation. The measurement model that uses these numbers lives in
:mod:`twin.instruments.noise` (noise and quantisation), :mod:`twin.instruments.aim`
(automatic aim), :mod:`twin.instruments.tilt` (compensation) and
:mod:`twin.instruments.shot` (one complete simulated shot).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

ARCSEC = math.pi / (180.0 * 3600.0)


def _check_positive(obj: object, names: tuple[str, ...], allow_zero: tuple[str, ...] = ()) -> None:
    for name in names:
        value = getattr(obj, name)
        ok = math.isfinite(value) and (value >= 0.0 if name in allow_zero else value > 0.0)
        if not ok:
            kind = "non-negative" if name in allow_zero else "positive"
            raise ValueError(f"{type(obj).__name__}.{name} must be finite and {kind}, got {value}")


@dataclass(frozen=True)
class TotalStationSpec:
    """Noise, resolution and range of a total station; defaults from the paper's Table I.

    Attributes:
        distance_sigma_const: constant part of the distance standard deviation, m.
        distance_sigma_ppm: distance-proportional part, parts per million of the distance.
        angle_sigma: standard deviation of each angle (horizontal and zenith), rad.
        distance_resolution: output resolution of the distance, m (0 = no quantisation).
        angle_resolution: output resolution of the angles, rad (0 = no quantisation).
        range_min, range_max: measurable slope distances, m.
        aim_cone: half-angle of the automatic aim's search cone, rad.
        pointing_sigma: where on the prism the instrument measures, m: the automatic aim's
            centring of the corner cube and the cube's own shift when seen off its axis, as
            a sideways error of each shot that does not shrink with the distance (standard
            deviation on each axis across the line of sight). Not in Table I; default 0.
    """

    distance_sigma_const: float = 2e-3
    distance_sigma_ppm: float = 2.0
    angle_sigma: float = 5.0 * ARCSEC
    distance_resolution: float = 0.2e-3
    angle_resolution: float = 1.0 * ARCSEC
    range_min: float = 1.3
    range_max: float = 2200.0
    aim_cone: float = 5.0 * math.pi / 180.0
    pointing_sigma: float = 0.0

    def __post_init__(self) -> None:
        _check_positive(
            self,
            (
                "distance_sigma_const",
                "distance_sigma_ppm",
                "angle_sigma",
                "distance_resolution",
                "angle_resolution",
                "range_min",
                "range_max",
                "aim_cone",
                "pointing_sigma",
            ),
            allow_zero=(
                "pointing_sigma",
                "distance_sigma_const",
                "distance_sigma_ppm",
                "angle_sigma",
                "distance_resolution",
                "angle_resolution",
            ),
        )
        if self.range_max <= self.range_min:
            raise ValueError(
                f"TotalStationSpec.range_max ({self.range_max} m) must exceed range_min "
                f"({self.range_min} m)"
            )
        if self.aim_cone >= math.pi / 2:
            raise ValueError(f"TotalStationSpec.aim_cone must be below pi/2, got {self.aim_cone}")

    def distance_sigma(self, distance: float) -> float:
        """Standard deviation of a slope distance ``distance`` (m), m."""
        return self.distance_sigma_const + self.distance_sigma_ppm * 1e-6 * distance

    @classmethod
    def noiseless(cls) -> TotalStationSpec:
        """A perfect instrument (no noise, no quantisation) with the default range and aim."""
        return cls(
            distance_sigma_const=0.0,
            distance_sigma_ppm=0.0,
            angle_sigma=0.0,
            distance_resolution=0.0,
            angle_resolution=0.0,
        )


@dataclass(frozen=True)
class InclinometerSpec:
    """Two-axis inclination sensor of the parent robot.

    Attributes:
        sigma: standard deviation of each tilt axis, rad (default 1 arc-second).
        working_range: largest tilt the compensator accepts on each axis, rad
            (default 3 arc-minutes).
    """

    sigma: float = 1.0 * ARCSEC
    working_range: float = 180.0 * ARCSEC

    def __post_init__(self) -> None:
        _check_positive(self, ("sigma", "working_range"), allow_zero=("sigma",))
