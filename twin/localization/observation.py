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

:class:`ChildObservationBatch` is one child's observation over T trials, built by
:func:`observe_child_batch` from the three cube shots of each trial without a Python object
per trial; where :func:`observe_child` (its one-trial form) raises
:class:`InconsistentMarkerError`, the batch keeps the trial and
:meth:`ChildObservationBatch.marker_inconsistent` flags it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.instruments.consistency import (
    DEFAULT_FALSE_ALARM_RATE,
    check_false_alarm_rate,
    exceeds_threshold,
    raise_if_inconsistent,
)
from twin.instruments.errors import InconsistentMarkerError
from twin.instruments.marker import MarkerAssembly
from twin.instruments.marker_pose import (
    MARKER_DOF,
    MarkerPose,
    check_cubes_batch,
    cube_centroid_batch,
    fit_marker_pose_batch,
)
from twin.instruments.noise import cartesian_covariance
from twin.instruments.polar import TotalStationMeasurement, polar2cartesian
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec
from twin.localization.input_checks import check_covariance, check_covariances


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


@dataclass(frozen=True, eq=False)
class ChildObservationBatch:
    """One child measured from the parent's current station, in T trials.

    Attributes:
        child: the child's name.
        point_level: (T, 3) its reference point in the parent's levelled frame, m.
        covariance: (T, 3, 3) covariance of ``point_level``, m^2.
        timestamp: time of the measurement, s (the same in every trial).
        marker_pose: the marker poses fitted to the three cubes, levelled frame (None when
            only the points were kept).
    """

    child: str
    point_level: NDArray[np.float64]
    covariance: NDArray[np.float64]
    timestamp: float = 0.0
    marker_pose: MarkerPose | None = None

    def __post_init__(self) -> None:
        p = np.array(self.point_level, dtype=float)
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(
                f"observation of {self.child!r}: point_level must be (T, 3), got {p.shape}"
            )
        if not np.all(np.isfinite(p)):
            raise ValueError(f"observation of {self.child!r}: point_level contains NaN or inf")
        c = np.array(self.covariance, dtype=float)
        if c.shape != (p.shape[0], 3, 3):
            raise ValueError(
                f"observation of {self.child!r}: covariance must be ({p.shape[0]}, 3, 3), "
                f"got {c.shape}"
            )
        check_covariances(c, 3, f"covariance of the observation of {self.child!r}")
        p.setflags(write=False)
        c.setflags(write=False)
        object.__setattr__(self, "point_level", p)
        object.__setattr__(self, "covariance", c)
        object.__setattr__(self, "timestamp", float(self.timestamp))

    @property
    def n_trials(self) -> int:
        """Number of trials T."""
        return self.point_level.shape[0]

    def marker_inconsistent(
        self, false_alarm_rate: float | None = DEFAULT_FALSE_ALARM_RATE
    ) -> NDArray[np.bool_]:
        """(T,) True where :func:`observe_child` would raise :class:`InconsistentMarkerError`
        (the marker chi-square above its quantile at ``false_alarm_rate``); all False
        without a marker pose or for rate None."""
        if self.marker_pose is None or self.marker_pose.chi2 is None:
            return np.zeros(self.n_trials, dtype=bool)
        return exceeds_threshold(self.marker_pose.chi2, self.marker_pose.dof, false_alarm_rate)

    def trial(self, index: int) -> ChildObservation:
        """The observation of one trial as a :class:`ChildObservation` (without shots)."""
        return ChildObservation(
            child=self.child,
            point_level=self.point_level[index],
            covariance=self.covariance[index],
            timestamp=self.timestamp,
            marker_pose=None if self.marker_pose is None else self.marker_pose.trial(index),
        )


def _observe(
    polar: NDArray[np.float64],
    cubes: NDArray[np.float64],
    spec: TotalStationSpec,
    inclinometer: InclinometerSpec | None,
    marker: MarkerAssembly | None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], MarkerPose]:
    """(T, 3) centroids, m, their (T, 3, 3) covariances, m^2, and the marker poses from
    (T, 3, 3) polar and Cartesian shots at the three cubes."""
    cov = cartesian_covariance(polar, spec, inclinometer)  # (T, 3, 3, 3)
    pose = fit_marker_pose_batch(cubes, marker if marker is not None else MarkerAssembly(), cov)
    point, point_cov = cube_centroid_batch(cubes, cov)
    return point, point_cov, pose


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
    points, covariances, poses = _observe(polar[None], cubes[None], spec, inclinometer, marker)
    pose = poses.trial(0)
    assert pose.chi2 is not None
    if exceeds_threshold(pose.chi2, MARKER_DOF, rate):
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
    return ChildObservation(
        child=child,
        point_level=points[0],
        covariance=covariances[0],
        timestamp=max(s.timestamp for s in cube_shots),
        shots=tuple(cube_shots),
        marker_pose=pose,
    )


def observe_child_batch(
    child: str,
    cubes_polar: ArrayLike,
    spec: TotalStationSpec,
    inclinometer: InclinometerSpec | None = None,
    *,
    cubes_level: ArrayLike | None = None,
    marker: MarkerAssembly | None = None,
    timestamp: float = 0.0,
) -> ChildObservationBatch:
    """A child's observation in T trials from the three shots at its cubes.

    Args:
        child: the child's name.
        cubes_polar: (T, 3, 3) levelled polar triplets (d m, hz rad, v rad) of the shots at
            cube 0, 1, 2 of ``marker.cubes_body``, in that order, in every trial.
        spec: the total station's specification (noise and resolution).
        inclinometer: the inclination sensor's specification; its noise enters the
            covariance (pass it for levelled shots, as :func:`observe_child` requires).
        cubes_level: (T, 3, 3) the same shots as Cartesian points of the levelled frame, m;
            default ``polar2cartesian(cubes_polar)``, what :func:`observe_child` uses.
        marker: the assembly geometry; default :class:`MarkerAssembly`'s.
        timestamp: time of the observation, s.

    Returns:
        The centroid and its covariance, with the marker poses and their chi-square (test
        them with :meth:`ChildObservationBatch.marker_inconsistent`).
    """
    polar = check_cubes_batch(cubes_polar, "cubes_polar")
    if polar.ndim != 3:
        raise ValueError(f"cubes_polar must have shape (T, 3, 3), got {polar.shape}")
    cubes = polar2cartesian(polar) if cubes_level is None else np.asarray(cubes_level, float)
    if cubes.shape != polar.shape:
        raise ValueError(
            f"cubes_level must have the shape of cubes_polar {polar.shape}, got {cubes.shape}"
        )
    point, point_cov, pose = _observe(polar, cubes, spec, inclinometer, marker)
    return ChildObservationBatch(child, point, point_cov, timestamp, pose)


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
