"""Input checks for the CPS solvers: ValueError naming the problem and the value.

What makes the parent's pose unobservable from its children is a zero horizontal baseline:
children that coincide, or that stand on one vertical line (same x, y; different heights).
Children on a line through the parent are fine: the pose of a planar rigid motion is fixed
by any two distinct horizontal points. A short baseline is not an error but poor geometry:
the solvers report the predicted yaw standard deviation and warn with
:class:`PoorGeometryWarning` above a threshold.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

DEFAULT_MIN_BASELINE = 1e-3
"""Smallest horizontal distance between two children (m) accepted as observable yaw."""

DEFAULT_MAX_YAW_STD = 1e-2
"""Predicted yaw standard deviation (rad, about 0.57 deg) above which a warning is raised."""


PSD_TOLERANCE = 1e-10
"""Most negative eigenvalue accepted in a covariance, relative to its largest (rounding)."""


class PoorGeometryWarning(UserWarning):
    """The yaw of the parent is observable but poorly: see the message's predicted figure."""


class ConvergenceWarning(UserWarning):
    """An iterative CPS solver stopped at its iteration limit before its step tolerance."""


def check_children_points(points: ArrayLike, name: str) -> NDArray[np.float64]:
    """Return child positions as a finite (N, 3) array with N >= 2, or raise ValueError."""
    arr = np.asarray(points, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), one row per child, got {arr.shape}")
    if arr.shape[0] < 2:
        raise ValueError(
            f"{name} has {arr.shape[0]} child(ren); CPS needs at least two children to solve "
            "the parent's yaw and translation"
        )
    bad = ~np.isfinite(arr)
    if bad.any():
        row = int(np.nonzero(bad)[0][0])
        raise ValueError(f"{name} contains NaN or inf, first in child {row}: {arr[row].tolist()}")
    return arr


def horizontal_baseline(points: NDArray[np.float64]) -> float:
    """Largest horizontal distance between two of the (N, 3) points, m."""
    xy = points[:, :2]
    diff = xy[:, None, :] - xy[None, :, :]
    return float(np.sqrt(np.max(np.sum(diff**2, axis=-1))))


def check_cps_input(
    children_world: ArrayLike,
    children_level: ArrayLike,
    min_baseline: float = DEFAULT_MIN_BASELINE,
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Check the children's world estimates and their new measurements.

    Args:
        children_world: (N, 3) children's positions in the world, m.
        children_level: (N, 3) the same children measured in the parent's levelled frame, m.
        min_baseline: smallest accepted horizontal baseline, m.

    Returns:
        The two arrays and the horizontal baseline (the smaller of the two frames'), m.

    Raises:
        ValueError: wrong shape, fewer than two children, NaN/inf, different numbers of
            children, or a horizontal baseline below ``min_baseline`` (yaw unobservable).
    """
    w = check_children_points(children_world, "children_world")
    m = check_children_points(children_level, "children_level")
    if w.shape != m.shape:
        raise ValueError(
            f"children_world has {w.shape[0]} children but children_level has {m.shape[0]}; "
            "each child needs a world position and a measurement"
        )
    baseline = min(horizontal_baseline(w), horizontal_baseline(m))
    if baseline < min_baseline:
        raise ValueError(
            f"the children coincide in the horizontal plane (largest horizontal separation "
            f"{baseline:.3g} m < {min_baseline:g} m): the parent's yaw is unobservable; "
            "place the children apart"
        )
    return w, m, baseline


def check_covariance(cov: ArrayLike, n: int, name: str) -> NDArray[np.float64]:
    """Return a finite, symmetric, positive semidefinite (n, n) covariance, or raise
    ValueError naming ``name`` (eigenvalues down to ``-PSD_TOLERANCE`` times the largest
    are accepted as rounding)."""
    c = np.asarray(cov, dtype=float)
    if c.shape != (n, n):
        raise ValueError(f"{name} must have shape ({n}, {n}), got {c.shape}")
    if not np.all(np.isfinite(c)):
        raise ValueError(f"{name} contains NaN or inf")
    # np.allclose(c, c.T, rtol=1e-8, atol=1e-15) for finite values, without its overhead.
    if not (np.abs(c - c.T) <= 1e-15 + 1e-8 * np.abs(c.T)).all():
        raise ValueError(f"{name} must be symmetric")
    eig = np.linalg.eigvalsh(0.5 * (c + c.T))
    if eig[0] < -PSD_TOLERANCE * np.abs(eig).max():
        raise ValueError(
            f"{name} is not positive semidefinite (smallest eigenvalue {eig[0]:.3g}); a "
            "covariance cannot have negative variances"
        )
    return c


def check_measurement_covariances(cov: ArrayLike | None, n: int) -> NDArray[np.float64]:
    """(n, 3, 3) per-child measurement covariances (None: zeros) -> (3n, 3n) block diagonal."""
    if cov is None:
        return np.zeros((3 * n, 3 * n))
    c = np.asarray(cov, dtype=float)
    if c.shape != (n, 3, 3):
        raise ValueError(f"cov_measurements must have shape ({n}, 3, 3), got {c.shape}")
    full = np.zeros((3 * n, 3 * n))
    for i in range(n):
        full[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] = c[i]
    return check_covariance(full, 3 * n, "cov_measurements")
