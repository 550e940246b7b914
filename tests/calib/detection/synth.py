"""Synthetic camera frames for the LED detector tests, made without MuJoCo.

A scene is a background (a smooth gradient with texture, 8-bit range) and LEDs drawn as
discs or Gaussian spots whose partial pixel coverage is integrated exactly enough (16 x 16
supersampling for discs, error functions for Gaussians) that the true position is known:
the disc's or Gaussian's centre, and the centroid of the noise-free sampled spot. Sensor
noise is Poisson shot noise plus Gaussian read noise, quantised to 8 bits.

Pixel convention: OpenCV, (u, v) = (column, row), (0, 0) the centre of the top-left pixel.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.special import erf

SUPERSAMPLE = 16


def background(
    shape: tuple[int, int],
    rng: np.random.Generator,
    *,
    low: float = 40.0,
    high: float = 170.0,
    texture: float = 12.0,
) -> NDArray[np.float64]:
    """(H, W) background, DN: a diagonal gradient from ``low`` to ``high`` plus texture."""
    h, w = shape
    rows, cols = np.indices(shape, dtype=float)
    grad = low + (high - low) * (0.6 * cols / max(w - 1, 1) + 0.4 * rows / max(h - 1, 1))
    blotches = cv2.GaussianBlur(rng.standard_normal(shape), (0, 0), 2.0)
    blotches *= texture / max(float(blotches.std()), 1e-12)
    stripes = 0.3 * texture * np.sin(cols / 3.1) * np.cos(rows / 4.3)
    return grad + blotches + stripes


def disc(shape: tuple[int, int], center: Sequence[float], diameter: float) -> NDArray:
    """(H, W) fraction of each pixel covered by a disc, by 16 x 16 supersampling."""
    h, w = shape
    u0, v0 = center
    r = diameter / 2.0
    out = np.zeros(shape)
    c0, c1 = max(int(np.floor(u0 - r)) - 1, 0), min(int(np.ceil(u0 + r)) + 2, w)
    r0, r1 = max(int(np.floor(v0 - r)) - 1, 0), min(int(np.ceil(v0 + r)) + 2, h)
    if c0 >= c1 or r0 >= r1:
        return out
    sub = (np.arange(SUPERSAMPLE) + 0.5) / SUPERSAMPLE - 0.5
    us = (np.arange(c0, c1)[:, None] + sub[None, :]).ravel()
    vs = (np.arange(r0, r1)[:, None] + sub[None, :]).ravel()
    inside = ((vs[:, None] - v0) ** 2 + (us[None, :] - u0) ** 2) <= r * r
    cover = inside.reshape(r1 - r0, SUPERSAMPLE, c1 - c0, SUPERSAMPLE).mean(axis=(1, 3))
    out[r0:r1, c0:c1] = cover
    return out


def gaussian(shape: tuple[int, int], center: Sequence[float], sigma: float) -> NDArray:
    """(H, W) a Gaussian of unit peak density integrated over each pixel (exact, by erf)."""
    h, w = shape

    def axis(n: int, c: float) -> NDArray[np.float64]:
        edges = (np.arange(n + 1) - 0.5 - c) / (np.sqrt(2.0) * sigma)
        return np.sqrt(np.pi / 2.0) * sigma * np.diff(erf(edges))

    return np.outer(axis(h, center[1]), axis(w, center[0]))


def sampled_centroid(spot: NDArray[np.float64]) -> NDArray[np.float64]:
    """(2,) intensity centroid (u, v) of a noise-free spot image."""
    rows, cols = np.indices(spot.shape, dtype=float)
    total = spot.sum()
    return np.array([(spot * cols).sum() / total, (spot * rows).sum() / total])


@dataclass(frozen=True)
class Led:
    """An LED in the image: centre (u, v) px, disc diameter px, brightness above the
    background DN (a disc's level; for ``gauss_sigma`` > 0 a Gaussian's peak instead)."""

    center: tuple[float, float]
    diameter: float = 4.0
    peak: float = 80.0
    gauss_sigma: float = 0.0

    def image(self, shape: tuple[int, int]) -> NDArray[np.float64]:
        """(H, W) the LED's light, DN."""
        if self.gauss_sigma > 0:
            return self.peak * gaussian(shape, self.center, self.gauss_sigma)
        return self.peak * disc(shape, self.center, self.diameter)


@dataclass(frozen=True)
class Sensor:
    """Read noise (DN), conversion gain (electrons per DN), quantisation to 8 bits."""

    read_dn: float = 2.0
    gain_e_per_dn: float = 10.0
    quantize: bool = True
    noisy: bool = True

    def expose(self, image: NDArray[np.float64], rng: np.random.Generator) -> NDArray:
        out = np.clip(image, 0.0, None)
        if self.noisy:
            out = rng.poisson(out * self.gain_e_per_dn) / self.gain_e_per_dn
            out = out + rng.normal(0.0, self.read_dn, out.shape)
        if self.quantize:
            return np.clip(np.round(out), 0, 255).astype(np.uint8)
        return out


NOISE_FREE = Sensor(noisy=False, quantize=False)
NOISE_FREE_8BIT = Sensor(noisy=False, quantize=True)


def render(
    pattern: NDArray[np.bool_],
    leds: Sequence[Led | None],
    rng: np.random.Generator,
    *,
    shape: tuple[int, int] = (120, 160),
    bg: NDArray[np.float64] | None = None,
    sensor: Sensor = Sensor(),
    light: Sequence[float] | None = None,
    extra: Sequence[NDArray[np.float64] | None] | None = None,
    cover: Sequence[tuple[NDArray[np.bool_], NDArray[np.float64]] | None] | None = None,
) -> NDArray:
    """Frames of a switching sequence: (n_frames, H, W).

    Args:
        pattern: (n_frames, n_leds) which LED is lit in which frame.
        leds: one Led per column (None: the LED is not in the image at all).
        light: (n_frames,) factor on the background light per frame (the LEDs keep theirs).
        extra: per frame, light added in front of everything (a lamp, a reflection), DN.
        cover: per frame, (mask, values): pixels replaced by an object in front (a person).
    """
    pattern = np.asarray(pattern, bool)
    base = background(shape, rng) if bg is None else bg
    led_images = [None if led is None else led.image(shape) for led in leds]
    frames = []
    for f, row in enumerate(pattern):
        img = base * (1.0 if light is None else light[f])
        for lit, li in zip(row, led_images, strict=True):
            if lit and li is not None:
                img = img + li
        if extra is not None and extra[f] is not None:
            img = img + extra[f]
        if cover is not None and cover[f] is not None:
            mask, values = cover[f]
            img = np.where(mask, values, img)
        frames.append(sensor.expose(img, rng))
    return np.stack(frames)


def mast_pixels(
    heights: Sequence[float],
    *,
    distance: float,
    lateral: float = 0.0,
    camera_height: float = 2.5,
    pitch_deg: float = 20.0,
    f: float = 770.0,
    center: tuple[float, float] = (160.0, 120.0),
) -> NDArray[np.float64]:
    """(n, 2) pixels of points on a vertical mast seen by a camera pitched down.

    The camera is at height ``camera_height`` (m) looking along +Y, tilted down by
    ``pitch_deg``; the mast stands at (lateral, distance) m on the floor.
    """
    t = np.radians(pitch_deg)
    fwd = np.array([0.0, np.cos(t), -np.sin(t)])
    right = np.array([1.0, 0.0, 0.0])
    down = np.cross(fwd, right)
    pts = np.array([[lateral, distance, h - camera_height] for h in heights])
    x, y, z = pts @ right, pts @ down, pts @ fwd
    return np.column_stack([center[0] + f * x / z, center[1] + f * y / z])
