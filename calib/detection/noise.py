"""Sensor noise: a signal-dependent model and its estimate from repeated dark frames.

The model is the usual photon-transfer one: read noise plus shot noise,

    sigma^2(I) = read_dn^2 + max(I - black_level_dn, 0) / gain_e_per_dn      (DN^2)

with I the pixel value in DN (digital numbers, the image's own units) and the gain in
electrons per DN. Quantisation noise (1/12 DN^2 for integer images) is part of the read term
when the model is estimated from images.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import nnls

MIN_BIN_PIXELS = 200  # fewest pixels per intensity bin in the noise fit
N_BINS = 16  # intensity bins (quantiles of the mean dark image)
CLIP_SIGMA = 4.0  # residuals beyond this many sigma are outliers (something moved)
MIN_RANGE_FOR_SLOPE = 8.0  # DN: a narrower intensity range cannot separate read and shot noise


@dataclass(frozen=True)
class NoiseModel:
    """Per-pixel noise of a camera: sigma^2(I) = read_dn^2 + max(I - black_level_dn, 0) / gain.

    Attributes:
        read_dn: noise at zero signal (read noise and quantisation), DN; > 0.
        gain_e_per_dn: conversion gain, electrons per DN; > 0. ``math.inf`` means no shot
            noise (the noise does not grow with the signal).
        black_level_dn: pixel value at zero light, DN.
    """

    read_dn: float
    gain_e_per_dn: float = math.inf
    black_level_dn: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.read_dn) and self.read_dn > 0):
            raise ValueError(f"read_dn must be a positive finite number of DN, got {self.read_dn}")
        if math.isnan(self.gain_e_per_dn) or self.gain_e_per_dn <= 0:
            raise ValueError(
                f"gain_e_per_dn must be positive (math.inf for no shot noise), "
                f"got {self.gain_e_per_dn}"
            )
        if not math.isfinite(self.black_level_dn):
            raise ValueError(f"black_level_dn must be finite, got {self.black_level_dn}")

    def variance(self, image: ArrayLike) -> NDArray[np.float64]:
        """Noise variance, DN^2, of each pixel of ``image`` (any shape, DN)."""
        signal = np.maximum(np.asarray(image, dtype=float) - self.black_level_dn, 0.0)
        return self.read_dn**2 + signal / self.gain_e_per_dn

    def sigma(self, image: ArrayLike) -> NDArray[np.float64]:
        """Noise standard deviation, DN, of each pixel of ``image``."""
        return np.sqrt(self.variance(image))


def _robust_sigma(x: NDArray[np.float64]) -> float:
    """Standard deviation of the bulk of ``x`` (zero-mean residuals): sigma-clipped at 4.

    Starts from the median absolute value and clips iteratively, so that a minority of
    outliers (a person walking through one frame) does not inflate the estimate, while
    integer-valued data (where the median absolute value is coarse) are still handled.
    """
    s = 1.4826 * float(np.median(np.abs(x)))
    if s == 0.0:
        s = float(np.sqrt(np.mean(x**2)))
    for _ in range(4):
        if s == 0.0:
            return 0.0
        keep = np.abs(x) <= CLIP_SIGMA * s
        s_new = float(np.sqrt(np.mean(x[keep] ** 2)))
        if abs(s_new - s) <= 1e-3 * s:
            return s_new
        s = s_new
    return s


def estimate_noise(
    dark_frames: ArrayLike,
    *,
    floor_dn: float = 0.5,
    valid: ArrayLike | None = None,
) -> NoiseModel:
    """Fit sigma^2(I) = read^2 + I / gain to repeated images of a static scene.

    The residuals of each frame from the per-pixel mean (scaled by sqrt(k / (k - 1)) for k
    frames, so each has the pixel's variance) are binned by the mean intensity; each bin's
    variance is estimated robustly (sigma clipping at 4), and the line through the bins is
    fitted by weighted non-negative least squares, dropping bins that disagree with it by
    more than half (a region that moved, saturation). Over a narrow intensity range (a flat
    scene) only a constant is fitted. The read noise is at least ``floor_dn``, so that
    noise-free (rendered, float) images get a usable threshold.

    Args:
        dark_frames: (k, H, W) k >= 2 images of the same scene, DN.
        floor_dn: smallest read noise returned, DN.
        valid: optional (H, W) bool, pixels to use (e.g. not saturated).

    Returns:
        The fitted NoiseModel (black level 0).
    """
    frames = np.asarray(dark_frames, dtype=float)
    if frames.ndim != 3 or frames.shape[0] < 2:
        raise ValueError(
            f"noise estimation needs (k, H, W) frames with k >= 2, got shape {frames.shape}"
        )
    if not (math.isfinite(floor_dn) and floor_dn > 0):
        raise ValueError(f"floor_dn must be positive, got {floor_dn}")
    k = frames.shape[0]
    mean = frames.mean(axis=0)
    resid = (frames - mean) * math.sqrt(k / (k - 1))
    use = np.ones(mean.shape, bool) if valid is None else np.asarray(valid, bool)
    level = mean[use]
    resid = resid[:, use]
    if level.size < MIN_BIN_PIXELS:
        raise ValueError(
            f"noise estimation needs at least {MIN_BIN_PIXELS} usable pixels, got {level.size}"
        )
    n_bins = max(1, min(N_BINS, level.size // MIN_BIN_PIXELS))
    order = np.argsort(level, kind="stable")
    bins = np.array_split(order, n_bins)
    centres = np.array([level[b].mean() for b in bins])
    var = np.array([_robust_sigma(resid[:, b].ravel()) ** 2 for b in bins])
    counts = np.array([b.size * k for b in bins], dtype=float)
    floor_var = floor_dn**2
    fit_slope = centres.max() - centres.min() >= MIN_RANGE_FOR_SLOPE and n_bins >= 3
    keep = np.ones(n_bins, bool)
    a, b = float(np.median(var)), 0.0
    for _ in range(n_bins):
        # Weights: the variance of a variance estimate is about 2 v^2 / n.
        w = np.sqrt(counts[keep] / 2.0) / np.maximum(var[keep], floor_var)
        if fit_slope and keep.sum() >= 3:
            design = np.column_stack([np.ones(keep.sum()), centres[keep]]) * w[:, None]
            (a, b), _ = nnls(design, var[keep] * w)
        else:
            a, b = float(np.sum(w**2 * var[keep]) / np.sum(w**2)), 0.0
        model = np.maximum(a + b * centres, floor_var)
        miss = np.where(keep, np.abs(np.maximum(var, floor_var) / model - 1.0), 0.0)
        worst = int(np.argmax(miss))
        if miss[worst] <= 0.5 or keep.sum() <= 3:
            break
        keep[worst] = False
    read = math.sqrt(max(float(a), floor_var))
    gain = 1.0 / float(b) if b > 0 else math.inf
    return NoiseModel(read_dn=read, gain_e_per_dn=gain)
