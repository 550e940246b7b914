"""Frames in: checks, conversion to one channel, and the light level of each frame.

Images are taken in their own units (DN: 0-255 for 8-bit, 0-65535 for 16-bit; floats as
given, not normalised). Pixel (0, 0) is the centre of the top-left pixel; arrays are indexed
[row, column] = [v, u].
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

CHANNELS = ("gray", "red", "green", "blue", "max")
COLOR_ORDERS = ("rgb", "bgr")
MIN_GAIN_PIXELS = 100  # fewest well-exposed pixels for a light-level estimate
MIN_GAIN = 0.02  # a frame darker than this relative to the reference is not compensated
MAX_GAIN_PIXELS = 20000  # well-exposed pixels used for it (a regular subsample)
WELL_EXPOSED_LOW = 0.05  # well exposed: reference above this fraction of full scale ...
WELL_EXPOSED_HIGH = 0.95  # ... and every frame below this fraction of saturation


@dataclass(frozen=True, eq=False)
class FrameStack:
    """Checked frames as one float channel.

    Attributes:
        images: (n_frames, H, W) float64, DN.
        saturated: (n_frames, H, W) bool, a channel at or above the saturation level.
        saturation_dn: the saturation level used, DN (inf for floats without one).
        notes: messages about the input (e.g. floats that look normalised).
    """

    images: NDArray[np.float64]
    saturated: NDArray[np.bool_]
    saturation_dn: float
    notes: tuple[str, ...] = ()


def _to_array(frames: ArrayLike | Sequence[ArrayLike]) -> NDArray:
    if isinstance(frames, np.ndarray):
        return frames
    items = list(frames)  # type: ignore[arg-type]
    if not items:
        raise ValueError("frames is empty; give one image per row of the switching pattern")
    arrays = [np.asarray(f) for f in items]
    first = arrays[0].shape
    for i, a in enumerate(arrays):
        if a.shape != first:
            raise ValueError(
                f"frame {i} has shape {a.shape} but frame 0 has {first}; every frame of a "
                "sequence must come from the same camera at the same size"
            )
    return np.stack(arrays)


def _full_scale(arr: NDArray) -> float:
    """Full scale of integer frames: the maximum of the type for 8 bits; for wider types
    the smallest 2^k - 1 (k >= 8) that holds the largest value, since 10-, 12- and 14-bit
    cameras deliver uint16 with the top bits empty. Floats: no saturation (inf)."""
    if arr.dtype.kind not in "iu":
        return np.inf
    top = int(np.iinfo(arr.dtype).max)
    if top <= 255:
        return float(top)
    bits = max(8, int(arr.max()).bit_length())
    return float(min(top, 2**bits - 1))


def load_frames(
    frames: ArrayLike | Sequence[ArrayLike],
    n_expected: int,
    *,
    channel: str = "gray",
    color_order: str = "rgb",
    saturation_dn: float | None = None,
) -> FrameStack:
    """Check frames and convert them to one float channel.

    Args:
        frames: (n, H, W) or (n, H, W, 3) array (uint8, uint16, other integers or float),
            or a sequence of n (H, W) or (H, W, 3) images.
        n_expected: number of frames the switching pattern has.
        channel: "gray" (mean of the channels), "red", "green", "blue" or "max".
        color_order: channel order of colour images, "rgb" or "bgr" (OpenCV's imread).
        saturation_dn: level at which a pixel saturates; None: the integer type's maximum,
            no saturation for floats.
    """
    arr = _to_array(frames)
    if arr.dtype == np.bool_ or arr.dtype.kind not in "iuf":
        raise ValueError(
            f"frames must be integer or float images, got dtype {arr.dtype}; "
            "convert to uint8, uint16 or float"
        )
    if arr.ndim not in (3, 4) or (arr.ndim == 4 and arr.shape[3] != 3):
        raise ValueError(
            f"frames must have shape (n_frames, H, W) or (n_frames, H, W, 3), got {arr.shape}"
        )
    if arr.shape[0] != n_expected:
        hint = ""
        if arr.ndim == 3 and arr.shape[2] == 3:
            hint = " (a single colour image? give a stack of frames, one per pattern row)"
        raise ValueError(
            f"got {arr.shape[0]} frames but the switching pattern has {n_expected} rows; "
            f"give exactly one frame per row{hint}"
        )
    if arr.shape[1] == 0 or arr.shape[2] == 0:
        raise ValueError(f"frames are empty images: shape {arr.shape}")
    if arr.dtype.kind == "f":
        bad = ~np.isfinite(arr)
        if bad.any():
            first = int(np.flatnonzero(bad.reshape(arr.shape[0], -1).any(axis=1))[0])
            raise ValueError(
                f"frames contain {int(bad.sum())} NaN or inf value(s), first in frame {first}; "
                "every pixel must be finite"
            )
    if channel not in CHANNELS:
        raise ValueError(f"channel must be one of {CHANNELS}, got {channel!r}")
    if color_order not in COLOR_ORDERS:
        raise ValueError(f"color_order must be one of {COLOR_ORDERS}, got {color_order!r}")
    sat = _full_scale(arr) if saturation_dn is None else float(saturation_dn)
    data = arr.astype(np.float64)
    if data.ndim == 4:
        saturated = (data >= sat).any(axis=3)
        if channel == "gray":
            data = data.mean(axis=3)
        elif channel == "max":
            data = data.max(axis=3)
        else:
            rgb = ("red", "green", "blue")
            index = rgb.index(channel) if color_order == "rgb" else 2 - rgb.index(channel)
            data = data[..., index]
    else:
        saturated = data >= sat
    notes = []
    if arr.dtype.kind == "f" and 0 < float(np.max(data)) <= 1.0:
        notes.append(
            f"float frames look normalised to [0, 1] (max {float(np.max(data)):.3g}); they "
            "are taken as DN, so the 0.5 DN noise floor is large: scale them to their full "
            "range (e.g. x 255) or give a NoiseModel and noise_floor_dn in those units"
        )
    return FrameStack(np.ascontiguousarray(data), saturated, sat, tuple(notes))


def estimate_gains(
    images: NDArray[np.float64],
    saturated: NDArray[np.bool_],
    dark: Sequence[int],
    saturation_dn: float,
) -> tuple[NDArray[np.float64], str | None]:
    """Light level of each frame relative to the dark reference frames.

    The gain of frame f is the median of frame / reference over well-exposed pixels (the
    reference above 5% of full scale, no frame at or near saturation), normalised so that
    the dark frames average 1; estimated twice, the second time against the reference
    rebuilt from the gain-compensated dark frames. The ratio is taken about 0 DN.

    Args:
        images: (n, H, W) frames, DN. saturated: (n, H, W) bool.
        dark: indices of the dark frames.
        saturation_dn: saturation level (inf if none).

    Returns:
        (n,) gains, and a message when they could not be estimated (then all 1).
    """
    n = images.shape[0]
    dark_idx = list(dark)
    reference = images[dark_idx].mean(axis=0)
    full = saturation_dn if np.isfinite(saturation_dn) else float(np.percentile(images, 99.9))
    valid = (reference > WELL_EXPOSED_LOW * full) & ~saturated.any(axis=0)
    if np.isfinite(saturation_dn):
        valid &= (images < WELL_EXPOSED_HIGH * saturation_dn).all(axis=0)
    count = int(valid.sum())
    if count < MIN_GAIN_PIXELS or full <= 0:
        return np.ones(n), (
            f"light level not estimated: only {count} well-exposed pixels "
            f"(need {MIN_GAIN_PIXELS}); frames are compared without gain compensation"
        )
    # A regular subsample is plenty: the median of 20000 ratios is good to ~1e-4.
    pick = np.flatnonzero(valid.ravel())[:: max(1, count // MAX_GAIN_PIXELS)]
    flat = images.reshape(n, -1)[:, pick]
    gains = np.ones(n)
    ref = reference
    for _ in range(2):
        ref_v = ref.ravel()[pick]
        gains = np.median(flat / ref_v, axis=1)
        gains /= gains[dark_idx].mean()
        ref = (images[dark_idx] / gains[dark_idx, None, None]).mean(axis=0)
    dead = ~np.isfinite(gains) | (gains < MIN_GAIN)
    if dead.any():
        f = int(np.flatnonzero(dead)[0])
        return np.ones(n), (
            f"light level not compensated: frame {f} is nearly black (level {gains[f]:.3g} of "
            "the dark reference)"
        )
    return gains, None
