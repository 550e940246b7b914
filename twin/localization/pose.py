"""The parent's pose estimate and a CPS solution record, for one trial or T at once.

:class:`ParentPoseBatch` and :class:`CpsSolutionBatch` hold T trials (what the solvers
compute); :class:`ParentPose` and :class:`CpsSolution` are one trial of them, with checks.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.rotation import rot_z
from twin.localization.input_checks import PoorGeometryWarning, check_covariance
from twin.localization.planar import level2world


@dataclass(frozen=True, eq=False)
class ParentPose:
    """Pose of the parent's levelled instrument frame L in the world W, with covariance.

    Attributes:
        yaw: rotation about the world z-axis, rad.
        translation: (3,) origin of L in W, m.
        covariance: (4, 4) covariance of (yaw rad, x m, y m, z m).
        timestamp: time the pose refers to, s.
    """

    yaw: float
    translation: NDArray[np.float64]
    covariance: NDArray[np.float64] = field(default_factory=lambda: np.zeros((4, 4)))
    timestamp: float = 0.0

    def __post_init__(self) -> None:
        t = np.array(self.translation, dtype=float).reshape(-1)
        c = np.array(self.covariance, dtype=float)
        if t.shape != (3,) or c.shape != (4, 4):
            raise ValueError(
                f"translation must be (3,) and covariance (4, 4), got {t.shape} and {c.shape}"
            )
        if not (np.isfinite(self.yaw) and np.all(np.isfinite(t)) and np.all(np.isfinite(c))):
            raise ValueError(f"parent pose must be finite, got yaw={self.yaw}, t={t}")
        check_covariance(c, 4, "the parent pose's covariance")
        t.setflags(write=False)
        c.setflags(write=False)
        object.__setattr__(self, "yaw", float(self.yaw))
        object.__setattr__(self, "translation", t)
        object.__setattr__(self, "covariance", c)

    @property
    def vector(self) -> NDArray[np.float64]:
        """(4,) (yaw, x, y, z)."""
        return np.concatenate([[self.yaw], self.translation])

    @property
    def rotation(self) -> NDArray[np.float64]:
        """(3, 3) level2world rotation Rz(yaw)."""
        return rot_z(self.yaw)

    @property
    def yaw_std(self) -> float:
        """Predicted standard deviation of the yaw, rad."""
        return float(np.sqrt(max(self.covariance[0, 0], 0.0)))

    @property
    def position_covariance(self) -> NDArray[np.float64]:
        """(3, 3) covariance of the translation, m^2."""
        return self.covariance[1:, 1:]

    @property
    def horizontal_std(self) -> float:
        """Predicted standard deviation of the horizontal position along its most
        uncertain axis, m."""
        largest = float(np.linalg.eigvalsh(self.covariance[1:3, 1:3]).max())
        return float(np.sqrt(max(largest, 0.0)))

    def level2world(self, points_level: ArrayLike) -> NDArray[np.float64]:
        """Map (..., 3) points of the levelled frame to the world (paper eq. 1), m."""
        return level2world(points_level, self.yaw, self.translation)


@dataclass(frozen=True, eq=False)
class CpsSolution:
    """The parent's pose solved from its children, with what produced it.

    Attributes:
        pose: the solved pose and its covariance.
        method: ``"closed_form"`` or ``"wls"``.
        children_jacobian: (4, 3N) d pose / d children world positions.
        measurement_jacobian: (4, 3N) d pose / d children measurements (levelled frame).
        baseline: horizontal baseline of the children, m.
        chi2: chi-square of the redundant equations with their predicted covariance:
            the weighted squared residual (WLS), or the baseline-length and
            height-difference mismatch (closed form). Mean ``dof`` for consistent data.
        dof: redundancy 3N - 4 (WLS) or 2 (closed form: the unused equations).
        iterations: Gauss-Newton iterations (0 for the closed form).
        converged: False if Gauss-Newton stopped at its iteration limit (a
            :class:`ConvergenceWarning` was raised).
    """

    pose: ParentPose
    method: str
    children_jacobian: NDArray[np.float64]
    measurement_jacobian: NDArray[np.float64]
    baseline: float
    chi2: float | None = None
    dof: int = 0
    iterations: int = 0
    converged: bool = True

    @property
    def yaw_std(self) -> float:
        """Predicted standard deviation of the solved yaw, rad."""
        return self.pose.yaw_std


@dataclass(frozen=True, eq=False)
class ParentPoseBatch:
    """Poses of the parent's levelled frame in the world over T trials, with covariance.

    A trial whose pose could not be solved (see :attr:`CpsSolutionBatch.poor_geometry`)
    holds NaN.

    Attributes:
        yaw: (T,) rotation about the world z-axis, rad.
        translation: (T, 3) origin of the levelled frame in the world, m.
        covariance: (T, 4, 4) covariance of (yaw rad, x m, y m, z m).
        timestamp: time the poses refer to, s (the same in every trial).
    """

    yaw: NDArray[np.float64]
    translation: NDArray[np.float64]
    covariance: NDArray[np.float64]
    timestamp: float = 0.0

    def __post_init__(self) -> None:
        yaw = np.array(self.yaw, dtype=float)
        t = np.array(self.translation, dtype=float)
        c = np.array(self.covariance, dtype=float)
        if yaw.ndim != 1 or t.shape != (yaw.size, 3) or c.shape != (yaw.size, 4, 4):
            raise ValueError(
                "yaw, translation and covariance must be (T,), (T, 3) and (T, 4, 4), got "
                f"{yaw.shape}, {t.shape} and {c.shape}"
            )
        for name, arr in (("yaw", yaw), ("translation", t), ("covariance", c)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "timestamp", float(self.timestamp))

    @classmethod
    def repeat(cls, pose: ParentPose, n_trials: int) -> ParentPoseBatch:
        """The same pose in each of ``n_trials`` trials."""
        if n_trials < 1:
            raise ValueError(f"n_trials must be at least 1, got {n_trials}")
        return cls(
            np.full(n_trials, pose.yaw),
            np.tile(pose.translation, (n_trials, 1)),
            np.tile(pose.covariance, (n_trials, 1, 1)),
            pose.timestamp,
        )

    @property
    def n_trials(self) -> int:
        """Number of trials T."""
        return self.yaw.size

    @property
    def vector(self) -> NDArray[np.float64]:
        """(T, 4) (yaw, x, y, z)."""
        return np.concatenate([self.yaw[:, None], self.translation], axis=1)

    @property
    def rotation(self) -> NDArray[np.float64]:
        """(T, 3, 3) level2world rotations Rz(yaw)."""
        return rot_z(self.yaw)

    @property
    def yaw_std(self) -> NDArray[np.float64]:
        """(T,) predicted standard deviation of the yaw, rad."""
        return np.sqrt(np.maximum(self.covariance[:, 0, 0], 0.0))

    def level2world(self, points_level: ArrayLike) -> NDArray[np.float64]:
        """Map (T, ..., 3) points of each trial's levelled frame to the world (eq. 1), m."""
        p = np.asarray(points_level, dtype=float)
        if p.ndim < 2 or p.shape[0] != self.n_trials or p.shape[-1] != 3:
            raise ValueError(f"points must have shape ({self.n_trials}, ..., 3), got {p.shape}")
        flat = p.reshape(self.n_trials, -1, 3)
        world = flat @ np.swapaxes(self.rotation, -1, -2) + self.translation[:, None, :]
        return world.reshape(p.shape)

    def trial(self, index: int) -> ParentPose:
        """The pose of one trial as a :class:`ParentPose`."""
        return ParentPose(
            self.yaw[index], self.translation[index], self.covariance[index], self.timestamp
        )


@dataclass(frozen=True, eq=False)
class CpsSolutionBatch:
    """The parent's pose solved from its children in T trials (see :class:`CpsSolution`).

    Where the one-trial solvers raise, the batch keeps going and flags the trial:

    Attributes:
        pose: the solved poses and their covariances.
        method: ``"closed_form"`` or ``"wls"``.
        children_jacobian: (T, 4, 3N) d pose / d children world positions.
        measurement_jacobian: (T, 4, 3N) d pose / d children measurements.
        baseline: (T,) horizontal baseline of the children (the smaller of the two
            frames'), m.
        chi2: (T,) chi-square of the redundant equations (mean ``dof`` when consistent).
        dof: its degrees of freedom, 3N - 4 (WLS) or 2 (closed form).
        iterations: (T,) Gauss-Newton iterations of each trial (0 for the closed form).
        converged: (T,) False where Gauss-Newton stopped at its iteration limit.
        inconsistent: (T,) True where the one-trial solver raises
            :class:`InconsistentChildrenError` (chi2 above its quantile at the false-alarm
            rate); the solution is kept.
        poor_geometry: (T,) True where the one-trial solver raises ValueError for a horizontal
            baseline below ``min_baseline`` (or NaN inputs): no solution, pose and
            Jacobians are NaN.
        poor_yaw: (T,) True where the one-trial solver warns with
            :class:`PoorGeometryWarning` (predicted yaw std above ``max_yaw_std``).
    """

    pose: ParentPoseBatch
    method: str
    children_jacobian: NDArray[np.float64]
    measurement_jacobian: NDArray[np.float64]
    baseline: NDArray[np.float64]
    chi2: NDArray[np.float64]
    dof: int
    iterations: NDArray[np.int64]
    converged: NDArray[np.bool_]
    inconsistent: NDArray[np.bool_]
    poor_geometry: NDArray[np.bool_]
    poor_yaw: NDArray[np.bool_]

    @property
    def failed(self) -> NDArray[np.bool_]:
        """(T,) True where the one-trial solver raises (inconsistent or poor geometry)."""
        return self.inconsistent | self.poor_geometry

    def trial(self, index: int) -> CpsSolution:
        """The solution of one trial as a :class:`CpsSolution` (ValueError if it has none)."""
        if self.poor_geometry[index]:
            raise ValueError(f"trial {index} has no solution (poor geometry)")
        return CpsSolution(
            pose=self.pose.trial(index),
            method=self.method,
            children_jacobian=self.children_jacobian[index],
            measurement_jacobian=self.measurement_jacobian[index],
            baseline=float(self.baseline[index]),
            chi2=float(self.chi2[index]),
            dof=self.dof,
            iterations=int(self.iterations[index]),
            converged=bool(self.converged[index]),
        )


def warn_if_poor(solution: CpsSolution, max_yaw_std: float) -> None:
    """Warn with :class:`PoorGeometryWarning` if the predicted yaw std exceeds the limit."""
    if solution.yaw_std > max_yaw_std:
        warnings.warn(
            f"poor CPS geometry: predicted yaw standard deviation {solution.yaw_std:.3g} rad "
            f"({np.degrees(solution.yaw_std):.3g} deg) exceeds {max_yaw_std:.3g} rad with a "
            f"horizontal baseline of {solution.baseline:.3g} m; spread the children further "
            "apart, across the line of sight",
            PoorGeometryWarning,
            stacklevel=3,
        )
