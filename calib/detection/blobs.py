"""Blobs: sub-pixel centroids with their predicted uncertainty, per-frame levels, code checks.

Arrays here are image crops indexed [row, column]; positions are returned as (u, v) =
(column, row) in the crop's own pixel coordinates (OpenCV convention: (0, 0) is the centre of
the top-left pixel), and the caller adds the crop's offset.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.special import ndtr

_INV_SQRT_2PI = 1.0 / math.sqrt(2.0 * math.pi)


def dilate(mask: NDArray[np.bool_], radius: int) -> NDArray[np.bool_]:
    """Dilate a boolean mask by a disc of ``radius`` pixels (a 3 x 3 square for 1)."""
    if radius <= 0:
        return mask.copy()
    shape = cv2.MORPH_RECT if radius == 1 else cv2.MORPH_ELLIPSE
    kernel = cv2.getStructuringElement(shape, (2 * radius + 1, 2 * radius + 1))
    return cv2.dilate(mask.astype(np.uint8), kernel).astype(bool)


def rectified_variance(
    mean: NDArray[np.float64], variance: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Variance of max(X, 0) for X ~ N(mean, variance), elementwise.

    Equals ``variance`` for a signal far above the noise and about 0.34 ``variance`` for no
    signal: the noise of the weights of a positive-part centroid.
    """
    s = np.sqrt(np.maximum(variance, 1e-300))
    z = mean / s
    cdf = ndtr(z)
    pdf = _INV_SQRT_2PI * np.exp(-0.5 * z * z)
    m1 = mean * cdf + s * pdf
    m2 = (mean * mean + variance) * cdf + mean * s * pdf
    return np.maximum(m2 - m1 * m1, 0.0)


def centroid(
    signal: NDArray[np.float64],
    window: NDArray[np.bool_],
    variance: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], float]:
    """Intensity-weighted centroid of the positive part of ``signal`` inside ``window``.

    c = sum(w x) / sum(w), w = max(signal, 0) on the window. Its predicted standard
    deviation comes from linearising: dc/dw_p = (x_p - c) / sum(w), with the variance of
    each weight that of a rectified Gaussian (see :func:`rectified_variance`).

    Args:
        signal: (h, w) background-free signal, DN.
        window: (h, w) bool, the pixels to use.
        variance: (h, w) variance of ``signal``, DN^2; None: no uncertainty (NaN).

    Returns:
        (2,) centroid (u, v) in the array's pixel coordinates, and the predicted standard
        deviation of each coordinate (root mean of the two variances), px. NaN if the window
        holds no positive signal.
    """
    weights = np.where(window, np.maximum(signal, 0.0), 0.0)
    total = float(weights.sum())
    if total <= 0.0:
        return np.full(2, np.nan), math.nan
    rows, cols = np.indices(signal.shape, dtype=float)
    u = float((weights * cols).sum() / total)
    v = float((weights * rows).sum() / total)
    sigma = math.nan
    if variance is not None:
        var_w = np.where(window, rectified_variance(signal, variance), 0.0)
        var_u = float((var_w * (cols - u) ** 2).sum()) / total**2
        var_v = float((var_w * (rows - v) ** 2).sum()) / total**2
        sigma = math.sqrt(0.5 * (var_u + var_v))
    return np.array([u, v]), sigma


def roundness(signal: NDArray[np.float64], window: NDArray[np.bool_]) -> float:
    """How round a spot is: the ratio of the smaller to the larger principal second moment
    of the positive part of ``signal`` inside ``window`` (1: a disc; 0: a line).

    The 1/12 px^2 that sampling by square pixels adds to each moment of any spot is taken
    off first, so small discs come out near 1 too. NaN without positive signal.
    """
    weights = np.where(window, np.maximum(signal, 0.0), 0.0)
    total = float(weights.sum())
    if total <= 0.0:
        return math.nan
    rows, cols = np.indices(signal.shape, dtype=float)
    u = (weights * cols).sum() / total
    v = (weights * rows).sum() / total
    cuu = (weights * (cols - u) ** 2).sum() / total - 1.0 / 12.0
    cvv = (weights * (rows - v) ** 2).sum() / total - 1.0 / 12.0
    cuv = (weights * (cols - u) * (rows - v)).sum() / total
    lam = np.linalg.eigvalsh(np.array([[cuu, cuv], [cuv, cvv]]))
    if lam[1] <= 0.0:
        return 1.0
    return float(max(lam[0], 0.0) / lam[1])


def frame_levels(
    diffs: NDArray[np.float64],
    variances: NDArray[np.float64],
    template: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Amplitude of a template in each frame, by least squares.

    a_f = sum(t D_f) / sum(t^2), so a frame that holds exactly the template has level 1;
    sigma_f = sqrt(sum(t^2 var_f)) / sum(t^2).

    Args:
        diffs: (n, h, w) frame differences from the reference, DN.
        variances: (n, h, w) their variances, DN^2.
        template: (h, w) non-negative template (zero outside the window).

    Returns:
        (n,) levels and (n,) their standard deviations, in units of the template.
    """
    t2 = float((template * template).sum())
    if t2 <= 0.0:
        n = diffs.shape[0]
        return np.zeros(n), np.full(n, np.inf)
    levels = np.einsum("fij,ij->f", diffs, template) / t2
    sigmas = np.sqrt(np.einsum("fij,ij->f", variances, template * template)) / t2
    return levels, sigmas


def check_code(
    levels: NDArray[np.float64],
    sigmas: NDArray[np.float64],
    lit: NDArray[np.bool_],
    off: NDArray[np.bool_],
    *,
    on_ratio: float,
    off_ratio: float,
    level_sigma: float,
) -> str | None:
    """Whether per-frame levels follow an on/off code; None if they do, else why not.

    Every lit frame must reach ``on_ratio`` of the brightest lit frame and every off frame
    (of ``off``) must stay within ``off_ratio`` of the dimmest lit frame, each test allowing
    ``level_sigma`` standard deviations of that frame's level.

    Args:
        levels, sigmas: (n,) per-frame levels and their standard deviations.
        lit: (n,) bool, the frames in which the LED is lit.
        off: (n,) bool, the frames in which it must be off (disjoint from ``lit``).
    """
    on_levels = levels[lit]
    top = float(on_levels.max())
    if top <= 0.0:
        return f"no positive level in its lit frames (max {top:.2g})"
    low_on = on_levels < on_ratio * top - level_sigma * sigmas[lit]
    if low_on.any():
        f = int(np.flatnonzero(lit)[np.argmax(low_on)])
        return (
            f"dim in lit frame {f}: level {levels[f] / top:.2f} of its brightest lit frame "
            f"(need >= {on_ratio:g})"
        )
    bottom = max(float(on_levels.min()), 0.0)
    bright_off = np.abs(levels[off]) > off_ratio * bottom + level_sigma * sigmas[off]
    if bright_off.any():
        f = int(np.flatnonzero(off)[np.argmax(bright_off)])
        return (
            f"not off in frame {f}: level {levels[f] / top:.2f} of its brightest lit frame "
            f"(need |level| <= {off_ratio:g} of its dimmest)"
        )
    return None
