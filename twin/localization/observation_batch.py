"""Children as the parent measured them, in many trials at once.

:class:`ChildObservationBatch` is one child's :class:`ChildObservation` over T trials: its
reference point (T, 3) in the parent's levelled frame and its (T, 3, 3) covariance.
:func:`observe_child_batch` builds it from the three cube shots of each trial as
:func:`twin.localization.observation.observe_child` does (covariance of the shots from
:func:`twin.instruments.noise.cartesian_covariance`, marker pose and its chi-square from
:func:`twin.instruments.marker_pose.fit_marker_pose_batch`, centroid and its
covariance), without a Python object per trial. Where the scalar function raises
:class:`InconsistentMarkerError`, the batch keeps the trial and
:meth:`ChildObservationBatch.marker_inconsistent` flags it: the caller counts the flags.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.instruments.consistency import DEFAULT_FALSE_ALARM_RATE, exceeds_threshold
from twin.instruments.marker import MarkerAssembly
from twin.instruments.marker_pose import MarkerPose as MarkerPoseBatch
from twin.instruments.marker_pose import (
    check_cubes_batch,
    cube_centroid_batch,
    fit_marker_pose_batch,
)
from twin.instruments.noise import cartesian_covariance
from twin.instruments.polar import polar2cartesian
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec
from twin.localization.input_checks_batch import check_covariances_batch
from twin.localization.observation import ChildObservation


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
    marker_pose: MarkerPoseBatch | None = None

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
        check_covariances_batch(c, 3, f"covariance of the observation of {self.child!r}")
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
    cov = cartesian_covariance(polar, spec, inclinometer)  # (T, 3, 3, 3)
    pose = fit_marker_pose_batch(cubes, marker if marker is not None else MarkerAssembly(), cov)
    point, point_cov = cube_centroid_batch(cubes, cov)
    return ChildObservationBatch(child, point, point_cov, timestamp, pose)
