"""A child as the parent measured it: its reference point in the parent's levelled frame.

CPS positions each child by one point: the centroid of its three corner cubes
(:attr:`MarkerAssembly.reference_body`). It is the mean of the three measured cubes, does
not depend on the child's heading, and averages the three shots' noise. The three raw
shots stay in the record for the marker pose (LED positions) and a later global adjustment.

The centroid alone cannot tell a wrong prism: if the automatic aim locked cube 1 for the
shot at cube 0 (it may, on a far child; see :mod:`twin.instruments.aim`), the mean of
(cube 1, cube 1, cube 2) is a point a few centimetres off, with a millimetre covariance.
:func:`observe_child` therefore fits the marker pose to the three cubes, labelled by the
aim (shot i at cube i), and raises :class:`InconsistentMarkerError` when the fit's
chi-square (3 degrees of freedom, see :mod:`twin.instruments.marker_pose`) exceeds its
quantile at ``false_alarm_rate`` (:mod:`twin.instruments.consistency`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.instruments.consistency import (
    DEFAULT_FALSE_ALARM_RATE,
    check_false_alarm_rate,
    raise_if_inconsistent,
)
from twin.instruments.errors import InconsistentMarkerError
from twin.instruments.marker import MarkerAssembly
from twin.instruments.marker_pose import MARKER_DOF, MarkerPose, cube_centroid, fit_marker_pose
from twin.instruments.noise import cartesian_covariance
from twin.instruments.polar import TotalStationMeasurement
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec
from twin.localization.input_checks import check_covariance


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
        marker_pose: the marker assembly's pose fitted to the three cubes, levelled frame
            (None in fast simulations that only keep the point).
    """

    child: str
    point_level: NDArray[np.float64]
    covariance: NDArray[np.float64]
    timestamp: float = 0.0
    shots: tuple[TotalStationMeasurement, ...] = ()
    marker_pose: MarkerPose | None = None

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
        check_covariance(c, 3, f"covariance of the observation of {self.child!r}")
        p.setflags(write=False)
        c.setflags(write=False)
        object.__setattr__(self, "point_level", p)
        object.__setattr__(self, "covariance", c)


def observe_child(
    child: str,
    cube_shots: Sequence[TotalStationMeasurement],
    spec: TotalStationSpec,
    inclinometer: InclinometerSpec | None = None,
    *,
    marker: MarkerAssembly | None = None,
    false_alarm_rate: float | None = DEFAULT_FALSE_ALARM_RATE,
) -> ChildObservation:
    """Build a child's observation from the three shots at its cubes.

    Args:
        child: the child's name.
        cube_shots: the shots aimed at cube 0, 1, 2 of ``marker.cubes_body``, in that order.
        spec: the total station's specification (noise and resolution).
        inclinometer: the inclination sensor's specification; its noise enters the
            covariance. Required when the shots carry tilt readings (levelled shots): leaving
            it out would drop the levelling error from the covariance.
        marker: the assembly geometry; default :class:`MarkerAssembly`'s.
        false_alarm_rate: probability that consistent shots raise
            :class:`InconsistentMarkerError`; None switches the test off.

    Raises:
        InconsistentMarkerError: the three cubes do not fit the assembly (wrong prism
            locked, or the child moved between shots); ``details`` hold ``chi2``, ``dof``,
            ``threshold``, ``rms_residual`` (m) and ``child``. Measure again.
        ValueError: not three shots, or levelled shots without ``inclinometer``.
    """
    rate = check_false_alarm_rate(false_alarm_rate)
    if len(cube_shots) != 3:
        raise ValueError(f"observation of {child!r} needs 3 cube shots, got {len(cube_shots)}")
    if inclinometer is None and any(s.tilt is not None for s in cube_shots):
        raise ValueError(
            f"observation of {child!r}: the shots were levelled with tilt readings; pass the "
            "inclinometer spec so that the levelling noise enters the covariance "
            "(InclinometerSpec(sigma=0.0) for an exact sensor)"
        )
    polar = np.array([s.polar for s in cube_shots])
    cubes = np.array([s.to_cartesian() for s in cube_shots])
    cov = cartesian_covariance(polar, spec, inclinometer)
    pose = fit_marker_pose(cubes, marker if marker is not None else MarkerAssembly(), cov)
    assert pose.chi2 is not None
    raise_if_inconsistent(
        pose.chi2,
        MARKER_DOF,
        rate,
        InconsistentMarkerError,
        f"child {child!r}: the three cube shots do not fit the marker assembly "
        f"(rms residual {pose.rms_residual * 1e3:.1f} mm; wrong prism or child moved)",
        rms_residual=pose.rms_residual,
        child=child,
    )
    point, point_cov = cube_centroid(cubes, cov)
    return ChildObservation(
        child=child,
        point_level=point,
        covariance=point_cov,
        timestamp=max(s.timestamp for s in cube_shots),
        shots=tuple(cube_shots),
        marker_pose=pose,
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
