"""Find the LEDs of a child robot in a sequence of frames from a fixed camera.

The robot switches its LEDs by a known :class:`SwitchingSequence`; the camera takes one
frame per row. Following the paper (an LED's image position is found by subtracting an
LED-off image from an LED-on image), for each LED:

1. every frame is divided by its light level (median ratio to the dark reference over
   well-exposed pixels), so that a light that dims does not produce differences;
2. the code-matched difference image is the mean of the frames where the LED is lit minus
   the mean of the code frames where it is off (or the dark reference if there are none);
   the other LEDs cancel or come out negative;
3. it is thresholded at ``threshold_sigma`` times its per-pixel noise (from the noise
   model, estimated from the dark frames or given), and split into connected components;
4. each component, dilated by ``dilate_px``, gives an intensity-weighted sub-pixel centroid
   (weights: the positive part of the signal) with its predicted standard deviation;
5. each component is checked: its level in every code frame must follow the LED's code,
   it must be small, away from the border, with enough SNR, and away from pixels that
   changed between the dark frames. Rejected components are kept with their reasons;
6. an LED with exactly one accepted candidate is found; otherwise the reason is classified
   (AMBIGUOUS, SCENE_CHANGED, TOO_FAINT, NOT_IN_VIEW, OCCLUDED, NOT_FOUND) and no position
   is given.

Steps 1 and 2 are here, 3 to 5 in :mod:`calib.detection.candidates`, 6 in
:mod:`calib.detection.verdicts`.

Pixel positions follow OpenCV: (u, v) = (column, row), (0, 0) the centre of the top-left
pixel. Nothing here depends on how the frames were made: rendered or from a real camera.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.detection.blobs import dilate
from calib.detection.candidates import Candidate, Prepared, measure_candidates
from calib.detection.config import DetectorConfig
from calib.detection.frames import estimate_gains, load_frames
from calib.detection.noise import NoiseModel, estimate_noise
from calib.detection.results import LedDetections
from calib.detection.sequence import SwitchingSequence, as_sequence
from calib.detection.verdicts import classify_leds, rejected_candidates

__all__ = ["detect_leds"]


def detect_leds(
    frames: ArrayLike | Sequence[ArrayLike],
    sequence: SwitchingSequence | ArrayLike,
    *,
    config: DetectorConfig = DetectorConfig(),  # noqa: B008 (frozen, immutable)
    noise: NoiseModel | None = None,
    led_line: ArrayLike | None = None,
) -> LedDetections:
    """Find the image position of every LED of a switching sequence.

    Args:
        frames: (n_frames, H, W) or (n_frames, H, W, 3) array (uint8, uint16 or float, in
            DN), or a sequence of n_frames such images; frame i was taken with the LEDs of
            row i of the pattern lit. Colour is reduced to one channel by
            ``config.channel``.
        sequence: the switching sequence (or its (n_frames, n_leds) bool pattern).
        config: detector settings.
        noise: the camera's noise model; None: estimated from the dark frames, which then
            must be two or more.
        led_line: optional (n_leds,) positions of the LEDs along the straight line they are
            mounted on, m (their heights on the mast). With it, a missing LED whose place
            (predicted from at least three found ones) is inside the image is OCCLUDED, one
            outside NOT_IN_VIEW.

    Returns:
        One LedDetection per LED (position with quality, or failure), the noise model, the
        frames' light levels, the rejected candidates and notes.

    Raises:
        ValueError: frames that do not match the pattern (count, shape, ndim, dtype,
            non-finite values, empty), a single dark frame without ``noise``, a bad
            ``led_line``.
    """
    seq = as_sequence(sequence)
    if not isinstance(config, DetectorConfig):
        raise ValueError(f"config must be a DetectorConfig, got {type(config).__name__}")
    if noise is not None and not isinstance(noise, NoiseModel):
        raise ValueError(f"noise must be a NoiseModel or None, got {type(noise).__name__}")
    stack = load_frames(
        frames,
        seq.n_frames,
        channel=config.channel,
        color_order=config.color_order,
        saturation_dn=config.saturation_dn,
    )
    line = _check_led_line(led_line, seq.n_leds)
    dark = list(seq.dark_frames)
    if noise is None and len(dark) < 2:
        raise ValueError(
            f"the pattern has {len(dark)} dark frame, so the noise cannot be estimated from "
            "the frames: give noise=NoiseModel(read_dn=..., gain_e_per_dn=...) for this "
            "camera, or use a pattern with two or more dark frames"
        )
    messages = list(stack.notes)
    images = stack.images
    n = images.shape[0]

    if config.compensate_gain:
        gains, note = estimate_gains(images, stack.saturated, dark, stack.saturation_dn)
        if note:
            messages.append(note)
    else:
        gains = np.ones(n)
    off_level = np.abs(gains - 1.0) > config.gain_tolerance
    for f in np.flatnonzero(off_level):
        messages.append(
            f"frame {int(f)}: light level {gains[f]:.3f} x the dark reference "
            f"({100 * (gains[f] - 1):+.1f}%), compensated"
        )
    comp = images / gains[:, None, None]
    reference = comp[dark].mean(axis=0)

    if noise is None:
        valid = ~stack.saturated[dark].any(axis=0)
        noise = estimate_noise(comp[dark], floor_dn=config.noise_floor_dn, valid=valid)
    var = np.maximum(noise.variance(images), config.noise_floor_dn**2) / gains[:, None, None] ** 2
    var_ref = var[dark].sum(axis=0) / len(dark) ** 2

    changed, changed_fraction = _changed_pixels(comp[dark], var[dark], config)
    if changed_fraction > 0:
        messages.append(
            f"{100 * changed_fraction:.2f}% of the pixels changed between the dark frames "
            "(something moved); candidates there are not used"
        )
    prep = Prepared(
        comp, var, reference, var_ref, stack.saturated, dilate(changed, config.dilate_px)
    )

    candidates: list[list[Candidate]] = []
    for led in range(seq.n_leds):
        cands, note = measure_candidates(prep, seq, led, config)
        candidates.append(cands)
        if note:
            messages.append(note)

    detections = classify_leds(prep, seq, candidates, line, config)
    rejected = rejected_candidates(candidates, seq, images.shape[1:])
    return LedDetections(
        leds=tuple(detections),
        noise=noise,
        frame_gains=gains,
        rejected=tuple(rejected),
        changed_fraction=changed_fraction,
        light_changed=bool(off_level.any()),
        messages=tuple(messages),
    )


# -- inputs ---------------------------------------------------------------------------------
def _check_led_line(led_line: ArrayLike | None, n_leds: int) -> NDArray[np.float64] | None:
    if led_line is None:
        return None
    line = np.asarray(led_line, dtype=float)
    if line.shape != (n_leds,):
        raise ValueError(
            f"led_line must have one position per LED, shape ({n_leds},), got {line.shape}"
        )
    if not np.isfinite(line).all():
        raise ValueError(f"led_line must be finite, got {line.tolist()}")
    if np.unique(line).size != n_leds:
        raise ValueError(f"led_line positions must be distinct, got {line.tolist()}")
    return line


def _changed_pixels(
    dark: NDArray[np.float64], var: NDArray[np.float64], config: DetectorConfig
) -> tuple[NDArray[np.bool_], float]:
    """Pixels whose dark frames differ by more than change_sigma sigma of a difference."""
    if dark.shape[0] < 2:
        return np.zeros(dark.shape[1:], bool), 0.0
    spread = dark.max(axis=0) - dark.min(axis=0)
    limit = config.change_sigma * np.sqrt(2.0 * var.mean(axis=0))
    mask = (spread > limit).astype(np.uint8)
    if not mask.any():
        return mask.astype(bool), 0.0
    _, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    small = np.flatnonzero(stats[:, cv2.CC_STAT_AREA] < config.min_change_area_px)
    keep = ~np.isin(labels, small) & (labels > 0)
    return keep, float(keep.mean())
