"""Input checks for the CPS solvers: ValueError naming the problem and the value.

What makes the parent's pose unobservable from its children is a zero horizontal baseline:
children that coincide, or that stand on one vertical line (same x, y; different heights).
Children on a line through the parent are fine: the pose of a planar rigid motion is fixed
by any two distinct horizontal points. A short baseline is not an error but poor geometry:
the solvers report the predicted yaw standard deviation and warn with
:class:`PoorGeometryWarning` above a threshold.

The solvers work on T trials at once and do not stop for one bad trial: what is wrong
with one trial's data (a horizontal baseline below ``min_baseline``, NaN) is a per-trial
flag, :func:`poor_geometry`; :func:`substitute_trials` replaces those trials' inputs by a
well-posed stand-in so that the batched linear algebra never meets a singular matrix, and
the solvers then overwrite their results with NaN. What is wrong for the batch as a whole
(shapes, a covariance that is not one) raises ValueError. The one-trial solvers check their
inputs with :func:`check_cps_pair` and :func:`check_covariance` and raise where a trial is
flagged (:func:`coincide_message`).
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


def coincide_message(baseline: float, min_baseline: float) -> str:
    """The ValueError text of a horizontal baseline (m) below ``min_baseline`` (m)."""
    return (
        f"the children coincide in the horizontal plane (largest horizontal separation "
        f"{baseline:.3g} m < {min_baseline:g} m): the parent's yaw is unobservable; "
        "place the children apart"
    )


def check_cps_pair(
    children_world: ArrayLike, children_level: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One trial's children's world estimates and new measurements, each a finite (N, 3)
    array with N >= 2 and the same N; ValueError naming the argument otherwise. The
    baseline is the solver's (:func:`poor_geometry`)."""
    w = check_children_points(children_world, "children_world")
    m = check_children_points(children_level, "children_level")
    if w.shape != m.shape:
        raise ValueError(
            f"children_world has {w.shape[0]} children but children_level has {m.shape[0]}; "
            "each child needs a world position and a measurement"
        )
    return w, m


def _first(mask: NDArray[np.bool_]) -> tuple[int, ...]:
    """Index of the first True entry of ``mask``."""
    return tuple(int(i) for i in np.argwhere(mask)[0])


def _trial(index: tuple[int, ...]) -> str:
    """The trial named in a message, or nothing for a single matrix."""
    if not index:
        return ""
    return f"trial {index[0] if len(index) == 1 else index}"


def check_covariance(cov: ArrayLike, n: int, name: str) -> NDArray[np.float64]:
    """Return a finite, symmetric, positive semidefinite (n, n) covariance, or raise
    ValueError naming ``name`` (eigenvalues down to ``-PSD_TOLERANCE`` times the largest
    are accepted as rounding): :func:`check_covariances` of one matrix."""
    c = np.asarray(cov, dtype=float)
    if c.shape != (n, n):
        raise ValueError(f"{name} must have shape ({n}, {n}), got {c.shape}")
    return check_covariances(c, n, name)


def check_covariances(cov: ArrayLike, n: int, name: str) -> NDArray[np.float64]:
    """Check every matrix of a (..., n, n) stack of covariances: finite, symmetric, positive
    semidefinite (eigenvalues down to ``-PSD_TOLERANCE`` times the largest are accepted as
    rounding).

    Returns the stack; raises ValueError naming ``name`` and the first failing trial.
    """
    c = np.asarray(cov, dtype=float)
    if c.ndim < 2 or c.shape[-2:] != (n, n):
        raise ValueError(f"{name} must have shape (..., {n}, {n}), got {c.shape}")
    if not np.isfinite(c).all():
        raise ValueError(f"{name} contains NaN or inf")
    ct = c.mT
    # np.allclose(c, c.T, rtol=1e-8, atol=1e-15) for finite values, without its overhead.
    close = np.abs(c - ct) <= 1e-15 + 1e-8 * np.abs(ct)
    if not close.all():
        trial = _trial(_first(~close.all(axis=(-1, -2))))
        raise ValueError(f"{name} must be symmetric" + (f" ({trial} is not)" if trial else ""))
    sym = 0.5 * (c + ct)
    if c.ndim > 2 and _positive_definite_within_tolerance(sym, n):
        return c
    eig = np.linalg.eigvalsh(sym)
    negative = eig[..., 0] < -PSD_TOLERANCE * np.abs(eig).max(axis=-1)
    if negative.any():
        index = _first(negative)
        trial = _trial(index)
        raise ValueError(
            f"{name} is not positive semidefinite ({trial + ': ' if trial else ''}smallest "
            f"eigenvalue {eig[index][0]:.3g}); a covariance cannot have negative variances"
        )
    return c


def _positive_definite_within_tolerance(sym: NDArray[np.float64], n: int) -> bool:
    """True if every matrix of the (..., n, n) symmetric stack passes the check without
    its eigenvalues (False: take them; one matrix takes them at once, which is faster)."""
    # Fast path: C + delta I positive definite, with delta = PSD_TOLERANCE * max |C_ii| (at
    # most PSD_TOLERANCE times the largest |eigenvalue|), proves every smallest eigenvalue
    # above the bound. Singular or bad matrices take the eigenvalues.
    diagonal = np.abs(np.diagonal(sym, axis1=-2, axis2=-1)).max(axis=-1)
    try:
        np.linalg.cholesky(sym + (PSD_TOLERANCE * diagonal)[..., None, None] * np.eye(n))
    except np.linalg.LinAlgError:
        return False
    return True


def check_measurement_covariances(cov: ArrayLike | None, n: int) -> NDArray[np.float64]:
    """(n, 3, 3) per-child measurement covariances (None: zeros) -> (3n, 3n) block diagonal."""
    if cov is None:
        return np.zeros((3 * n, 3 * n))
    c = np.asarray(cov, dtype=float)
    if c.shape != (n, 3, 3):
        raise ValueError(f"cov_measurements must have shape ({n}, 3, 3), got {c.shape}")
    return check_covariance(block_diagonal(c[None])[0], 3 * n, "cov_measurements")


def block_diagonal(blocks: NDArray[np.float64]) -> NDArray[np.float64]:
    """(T, N, k, k) blocks -> (T, kN, kN) block-diagonal matrices."""
    t, n, k = blocks.shape[:3]
    full = np.zeros((t, k * n, k * n))
    for i in range(n):
        full[:, k * i : k * i + k, k * i : k * i + k] = blocks[:, i]
    return full


def horizontal_baseline_batch(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """(T, N, 3) points -> (T,) largest horizontal distance between two of them, m."""
    xy = points[..., :2]
    diff = xy[:, :, None, :] - xy[:, None, :, :]
    return np.sqrt(np.max(np.sum(diff**2, axis=-1), axis=(-1, -2)))


def check_cps_input_batch(
    children_world: ArrayLike,
    children_level: ArrayLike,
    cov_children_world: ArrayLike | None,
    cov_measurements: ArrayLike | None,
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Shapes of the batched solvers' inputs; the covariances of the trials whose inputs
    are finite are checked by :func:`check_covariances`.

    Args:
        children_world: (T, N, 3) children's world positions, m (NaN in a lost trial).
        children_level: (T, N, 3) the children measured in the levelled frame, m.
        cov_children_world: (T, 3N, 3N) joint covariance of the world positions, m^2;
            None = 0.
        cov_measurements: (T, N, 3, 3) covariance of each measurement, m^2; None = 0.

    Returns:
        ``(world, level, cov_world, cov_level)``, the covariances (T, 3N, 3N).
    """
    w = np.asarray(children_world, dtype=float)
    m = np.asarray(children_level, dtype=float)
    if w.ndim != 3 or w.shape[2] != 3 or w.shape[1] < 2:
        raise ValueError(
            f"children_world must have shape (T, N, 3) with N >= 2 children, got {w.shape}"
        )
    if m.shape != w.shape:
        raise ValueError(f"children_level must have the shape {w.shape} of children_world")
    t, n = w.shape[:2]
    if cov_children_world is None:
        cw = np.zeros((t, 3 * n, 3 * n))
    else:
        cw = np.asarray(cov_children_world, dtype=float)
        if cw.shape != (t, 3 * n, 3 * n):
            raise ValueError(
                f"cov_children_world must have shape {(t, 3 * n, 3 * n)}, got {cw.shape}"
            )
    if cov_measurements is None:
        cm = np.zeros((t, 3 * n, 3 * n))
    else:
        blocks = np.asarray(cov_measurements, dtype=float)
        if blocks.shape != (t, n, 3, 3):
            raise ValueError(f"cov_measurements must have shape {(t, n, 3, 3)}, got {blocks.shape}")
        cm = block_diagonal(blocks)
    finite = (
        np.isfinite(w).all(axis=(1, 2))
        & np.isfinite(m).all(axis=(1, 2))
        & np.isfinite(cw).all(axis=(1, 2))
    )
    check_covariances(cw[finite], 3 * n, "cov_children_world")
    check_covariances(cm, 3 * n, "cov_measurements")
    return w, m, cw, cm


def poor_geometry(
    world: NDArray[np.float64], level: NDArray[np.float64], min_baseline: float
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Horizontal baseline (T,), m (the smaller of the two frames'), and (T,) True where
    a trial has no solution: baseline below ``min_baseline``, or NaN."""
    baseline = np.minimum(horizontal_baseline_batch(world), horizontal_baseline_batch(level))
    return baseline, ~(baseline >= min_baseline)


def substitute_trials(
    bad: NDArray[np.bool_],
    world: NDArray[np.float64],
    level: NDArray[np.float64],
    cov_world: NDArray[np.float64],
    cov_level: NDArray[np.float64],
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Copies of the inputs with the ``bad`` trials replaced by a well-posed problem.

    The stand-in is N children on a unit circle, the same in both frames, with unit
    covariances: every batched matrix is then regular. The callers overwrite the results
    of these trials with NaN.
    """
    if not bad.any():
        return world, level, cov_world, cov_level
    n = world.shape[1]
    angle = 2.0 * np.pi * np.arange(n) / n
    ring = np.stack([np.cos(angle), np.sin(angle), np.zeros(n)], axis=-1)
    eye = np.eye(3 * n)
    out = [arr.copy() for arr in (world, level, cov_world, cov_level)]
    for arr, value in zip(out, (ring, ring, eye, eye), strict=True):
        arr[bad] = value
    return out[0], out[1], out[2], out[3]
