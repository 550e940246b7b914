"""A child as the parent measured it: its reference point in the parent's levelled frame.

CPS positions each child by one point: the centroid of its three corner cubes
(:attr:`MarkerAssembly.reference_body`). It is the mean of the three measured cubes, does
not depend on the child's heading, and averages the three shots' noise. The three raw
shots stay in the record for the marker pose (LED positions) and a later global adjustment.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.instruments.marker_pose import cube_centroid
from twin.instruments.noise import cartesian_covariance
from twin.instruments.polar import TotalStationMeasurement
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec


@dataclass(frozen=True, eq=False)
class ChildObservation:
    """One child measured from the parent's current station.

    Attributes:
        child: the child's name.
        point_level: (3,) its reference point in the parent's levelled frame, m.
        covariance: (3, 3) covariance of ``point_level``, m^2.
        timestamp: time of the measurement, s.
        shots: the raw total-station measurements it was computed from (may be empty in
            fast simulations that only keep the point).
    """

    child: str
    point_level: NDArray[np.float64]
    covariance: NDArray[np.float64]
    timestamp: float = 0.0
    shots: tuple[TotalStationMeasurement, ...] = ()

    def __post_init__(self) -> None:
        p = np.array(self.point_level, dtype=float).reshape(-1)
        c = np.array(self.covariance, dtype=float)
        if p.shape != (3,) or c.shape != (3, 3):
            raise ValueError(
                f"observation of {self.child!r}: point_level must be (3,) and covariance "
                f"(3, 3), got {p.shape} and {c.shape}"
            )
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(c))):
            raise ValueError(
                f"observation of {self.child!r} contains NaN or inf: point {p.tolist()}"
            )
        p.setflags(write=False)
        c.setflags(write=False)
        object.__setattr__(self, "point_level", p)
        object.__setattr__(self, "covariance", c)


def observe_child(
    child: str,
    cube_shots: Sequence[TotalStationMeasurement],
    spec: TotalStationSpec,
    inclinometer: InclinometerSpec | None = None,
) -> ChildObservation:
    """Build a child's observation from the three shots at its cubes (in cube order)."""
    if len(cube_shots) != 3:
        raise ValueError(f"observation of {child!r} needs 3 cube shots, got {len(cube_shots)}")
    polar = np.array([s.polar for s in cube_shots])
    cubes = np.array([s.to_cartesian() for s in cube_shots])
    cov = cartesian_covariance(polar, spec, inclinometer)
    point, point_cov = cube_centroid(cubes, cov)
    return ChildObservation(
        child=child,
        point_level=point,
        covariance=point_cov,
        timestamp=max(s.timestamp for s in cube_shots),
        shots=tuple(cube_shots),
    )


def reference_from_cubes(
    cubes_level: ArrayLike,
    cubes_polar: ArrayLike,
    spec: TotalStationSpec,
    inclinometer: InclinometerSpec | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Vectorised reference points from measured cubes.

    Args:
        cubes_level: (..., 3, 3) measured cubes (Cartesian, levelled frame), m.
        cubes_polar: (..., 3, 3) the same as polar triplets.
        spec, inclinometer: the instrument's specifications.

    Returns:
        (..., 3) centroids, m, and (..., 3, 3) their covariances, m^2.
    """
    cov = cartesian_covariance(cubes_polar, spec, inclinometer)
    return np.mean(cubes_level, axis=-2), np.sum(cov, axis=-3) / 9.0
