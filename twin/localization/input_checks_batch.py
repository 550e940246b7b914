"""Input checks of the batched CPS solvers (T trials at once; see :mod:`.input_checks`).

A batch does not stop for one bad trial. What the scalar solvers refuse with ValueError
because of the data of one trial (a horizontal baseline below ``min_baseline``, NaN) is a
per-trial flag here, :func:`poor_geometry`; :func:`substitute_trials` replaces those
trials' inputs by a well-posed stand-in so that the batched linear algebra never meets a
singular matrix, and the solvers then overwrite their results with NaN. What is wrong for
the batch as a whole (shapes, a covariance that is not one) still raises ValueError.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.localization.input_checks import PSD_TOLERANCE


def _first(mask: NDArray[np.bool_]) -> tuple[int, ...]:
    """Index of the first True entry of ``mask``."""
    return tuple(int(i) for i in np.argwhere(mask)[0])


def _name(index: tuple[int, ...]) -> str:
    return str(index[0]) if len(index) == 1 else str(index)


def check_covariances_batch(cov: ArrayLike, n: int, name: str) -> NDArray[np.float64]:
    """:func:`.input_checks.check_covariance` of every matrix of a (..., n, n) stack.

    Returns the stack; raises ValueError naming ``name`` and the first failing trial.
    """
    c = np.asarray(cov, dtype=float)
    if c.ndim < 2 or c.shape[-2:] != (n, n):
        raise ValueError(f"{name} must have shape (..., {n}, {n}), got {c.shape}")
    if not np.all(np.isfinite(c)):
        raise ValueError(f"{name} contains NaN or inf")
    ct = np.swapaxes(c, -1, -2)
    asym = ~(np.abs(c - ct) <= 1e-15 + 1e-8 * np.abs(ct)).all(axis=(-1, -2))
    if asym.any():
        raise ValueError(f"{name} must be symmetric (trial {_name(_first(asym))} is not)")
    sym = 0.5 * (c + ct)
    # Fast path: C + delta I positive definite, with delta = PSD_TOLERANCE * max |C_ii| (at
    # most PSD_TOLERANCE times the largest |eigenvalue|), proves every smallest eigenvalue
    # above the scalar check's bound. Singular or bad matrices take the eigenvalues.
    diagonal = np.abs(np.diagonal(sym, axis1=-2, axis2=-1)).max(axis=-1)
    try:
        np.linalg.cholesky(sym + (PSD_TOLERANCE * diagonal)[..., None, None] * np.eye(n))
    except np.linalg.LinAlgError:
        pass
    else:
        return c
    eig = np.linalg.eigvalsh(sym)
    negative = eig[..., 0] < -PSD_TOLERANCE * np.abs(eig).max(axis=-1)
    if negative.any():
        trial = _first(negative)
        raise ValueError(
            f"{name} is not positive semidefinite (trial {_name(trial)}: smallest eigenvalue "
            f"{eig[trial][0]:.3g}); a covariance cannot have negative variances"
        )
    return c


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
    are finite are checked as :func:`.input_checks.check_covariance` does.

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
    check_covariances_batch(cw[finite], 3 * n, "cov_children_world")
    check_covariances_batch(cm, 3 * n, "cov_measurements")
    return w, m, cw, cm


def poor_geometry(
    world: NDArray[np.float64], level: NDArray[np.float64], min_baseline: float
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Horizontal baseline (T,), m (the smaller of the two frames'), and (T,) True where
    the scalar solvers raise ValueError: baseline below ``min_baseline``, or NaN."""
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
