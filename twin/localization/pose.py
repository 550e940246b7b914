"""The parent's pose estimate and a CPS solution record."""

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
