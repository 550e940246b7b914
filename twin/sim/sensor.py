"""The image sensor: from rendered light levels to the numbers a camera delivers.

For each pixel and colour channel, with level L in [0, 1] from the render (after the lens
and pixel integration of :mod:`twin.sim.lens`):

    electrons = exposure * L * full_well_e + Normal(0, sqrt(that + read_noise_e**2))
    DN        = round(electrons / full_well_e * (2**bits - 1)), clipped to [0, 2**bits - 1]

after a Gaussian blur of the levels (lens and sensor blur). Photon (Poisson) noise is drawn
in its Gaussian form, with the Poisson variance: exact in mean and variance, and within a
fraction of a DN of the Poisson shape down to a few electrons, where the read noise
dominates anyway; one normal draw in float32 is about six times faster than
``rng.poisson``. The noise in DN at level L is
therefore ``sqrt(exposure * L * full_well_e + read_noise_e**2) * gain`` with
``gain = (2**bits - 1) / full_well_e``: :func:`noise_dn` gives it, for thresholds and tests.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.scenario.schema import SensorConfig


def dn_per_electron(sensor: SensorConfig) -> float:
    """Conversion gain, DN per electron."""
    return (2**sensor.bits - 1) / sensor.full_well_e


def noise_dn(sensor: SensorConfig, level_dn: ArrayLike) -> NDArray[np.float64]:
    """Standard deviation of a pixel's value (DN) at mean value ``level_dn`` (DN), before
    quantisation; 0 when the sensor is noise-free."""
    dn = np.asarray(level_dn, dtype=float)
    if not sensor.noise:
        return np.zeros_like(dn)
    g = dn_per_electron(sensor)
    electrons = np.clip(dn, 0.0, None) / g
    return g * np.sqrt(electrons + sensor.read_noise_e**2)


def expose(
    levels: NDArray[np.floating],
    sensor: SensorConfig,
    rng: np.random.Generator | None,
    full_scale: float = 255.0,
) -> NDArray[np.uint8] | NDArray[np.uint16]:
    """One exposure of the sensor.

    Args:
        levels: (H, W) or (H, W, C) rendered light levels; ``full_scale`` is white.
        sensor: the sensor's settings.
        rng: random generator for the noise (unused, and may be None, when the sensor is
            noise-free).
        full_scale: the level that means white at unit exposure (255 for a uint8 render).

    Returns:
        The image, same shape: uint8 for 8 bits, uint16 for more.
    """
    lv = np.asarray(levels, dtype=np.float32) / np.float32(full_scale)
    if sensor.blur_sigma_px > 0:
        lv = cv2.GaussianBlur(
            lv, (0, 0), sigmaX=sensor.blur_sigma_px, borderType=cv2.BORDER_REPLICATE
        )
    electrons = np.clip(lv, 0.0, None) * np.float32(sensor.exposure * sensor.full_well_e)
    if sensor.noise:
        if rng is None:
            raise ValueError("a noisy sensor needs a random generator")
        sigma = np.sqrt(electrons + np.float32(sensor.read_noise_e**2))
        electrons = electrons + sigma * rng.standard_normal(electrons.shape, dtype=np.float32)
    top = 2**sensor.bits - 1
    dn = np.clip(np.rint(electrons * np.float32(dn_per_electron(sensor))), 0, top)
    return dn.astype(np.uint8 if sensor.bits == 8 else np.uint16)
