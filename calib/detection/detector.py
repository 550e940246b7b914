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

Pixel positions follow OpenCV: (u, v) = (column, row), (0, 0) the centre of the top-left
pixel. Nothing here depends on how the frames were made: rendered or from a real camera.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from calib.detection.blobs import centroid, check_code, dilate, frame_levels, roundness
from calib.detection.classify import find_faint, inside_image, predict_on_line
from calib.detection.config import DetectorConfig
from calib.detection.frames import estimate_gains, load_frames
from calib.detection.noise import NoiseModel, estimate_noise
from calib.detection.results import (
    DetectionFailure,
    LedDetection,
    LedDetections,
    RejectedCandidate,
    RejectReason,
)
from calib.detection.sequence import SwitchingSequence, as_sequence

__all__ = ["detect_leds"]

MAX_CANDIDATES = 200  # components measured per LED (the brightest); more are only counted
MIN_LINE_LEDS = 3  # found LEDs needed to predict a missing one's place on the mast


@dataclass(frozen=True, eq=False)
class _Candidate:
    led: int
    pixel: NDArray[np.float64]
    sigma_px: float
    area: int
    peak: float
    snr: float
    levels: NDArray[np.float64]
    reasons: tuple[RejectReason, ...]
    message: str
    box: tuple[slice, slice]
    window: NDArray[np.bool_]
    saturated: bool
    roundness: float


@dataclass(frozen=True, eq=False)
class _Prepared:
    """Frames after gain compensation, with their noise."""

    comp: NDArray[np.float64]  # (n, H, W) gain-compensated frames, DN
    var: NDArray[np.float64]  # (n, H, W) their variances, DN^2
    reference: NDArray[np.float64]  # (H, W) mean of the dark frames
    var_ref: NDArray[np.float64]  # (H, W) its variance
    saturated: NDArray[np.bool_]  # (n, H, W)
    changed: NDArray[np.bool_]  # (H, W) changed between dark frames, dilated


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
    prep = _Prepared(
        comp, var, reference, var_ref, stack.saturated, dilate(changed, config.dilate_px)
    )

    candidates: list[list[_Candidate]] = []
    for led in range(seq.n_leds):
        cands, note = _candidates(prep, seq, led, config)
        candidates.append(cands)
        if note:
            messages.append(note)

    detections = _classify(prep, seq, candidates, line, config)
    rejected = _rejected(candidates, seq, images.shape[1:])
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


# -- candidates -----------------------------------------------------------------------------
def _matched(
    prep: _Prepared, lit: NDArray[np.bool_], off: NDArray[np.bool_]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Code-matched difference image, its variance, the off baseline and its variance."""
    n_lit = int(lit.sum())
    on = prep.comp[lit].mean(axis=0)
    var_on = prep.var[lit].sum(axis=0) / n_lit**2
    if off.any():
        n_off = int(off.sum())
        base = prep.comp[off].mean(axis=0)
        var_base = prep.var[off].sum(axis=0) / n_off**2
    else:
        base, var_base = prep.reference, prep.var_ref
    return on - base, var_on + var_base, base, var_base


def _candidates(
    prep: _Prepared, seq: SwitchingSequence, led: int, config: DetectorConfig
) -> tuple[list[_Candidate], str | None]:
    lit = seq.pattern[:, led]
    code = seq.pattern.any(axis=1)
    off = code & ~lit
    matched, matched_var, base, var_base = _matched(prep, lit, off)
    above = matched > config.threshold_sigma * np.sqrt(matched_var)
    # Components closer than their centroid windows are one candidate: the window of a
    # component is its dilation, and a faint spot that breaks up stays one blob.
    grouped = dilate(above, config.dilate_px).astype(np.uint8)
    n_lab, labels, stats, _ = cv2.connectedComponentsWithStats(grouped, connectivity=8)
    if n_lab <= 1:
        return [], None
    index = np.arange(1, n_lab)
    peaks = np.asarray(ndimage.maximum(matched, labels, index), dtype=float)
    order = index[np.argsort(-peaks, kind="stable")]
    note = None
    if order.size > MAX_CANDIDATES:
        note = (
            f"LED {led}: {order.size} candidates above threshold, only the "
            f"{MAX_CANDIDATES} brightest measured (a large change in the scene?)"
        )
        order = order[:MAX_CANDIDATES]
    h, w = matched.shape
    out = []
    for lab in order:
        x, y, bw, bh, _ = (int(v) for v in stats[lab])
        box = np.s_[y : y + bh, x : x + bw]
        window = labels[box] == lab
        comp_mask = window & above[box]
        area = int(comp_mask.sum())
        rows, cols = np.nonzero(comp_mask)
        sig = matched[box]
        sig_var = matched_var[box]
        c, sigma_px = centroid(sig, window, sig_var)
        pixel = c + np.array([x, y], dtype=float)
        peak = float(sig[comp_mask].max())
        core = dilate(comp_mask, 1) & window
        snr = float(sig[core].sum() / math.sqrt(sig_var[core].sum()))
        reasons: list[RejectReason] = []
        why: list[str] = []
        if area > config.max_area_px:
            reasons.append(RejectReason.TOO_LARGE)
            why.append(f"area {area} px > max_area_px {config.max_area_px}")
        if (
            y + rows.min() == 0
            or x + cols.min() == 0
            or y + rows.max() == h - 1
            or (x + cols.max() == w - 1)
        ):
            reasons.append(RejectReason.AT_BORDER)
            why.append("touches the image border")
        scene = bool((prep.changed[box] & window).any())
        if scene:
            reasons.append(RejectReason.SCENE_CHANGED)
            why.append("overlaps pixels that changed between the dark frames")
        # Per-frame levels against the dark reference; where the dark frames disagree,
        # against the code frames with the LED off (the reference is not to be trusted).
        template = np.where(window, np.maximum(sig, 0.0), 0.0)
        if scene and off.any():
            diffs = prep.comp[:, box[0], box[1]] - base[box]
            dvar = prep.var[:, box[0], box[1]] + var_base[box]
        else:
            diffs = prep.comp[:, box[0], box[1]] - prep.reference[box]
            dvar = prep.var[:, box[0], box[1]] + prep.var_ref[box]
        levels, level_sig = frame_levels(diffs, dvar, template)
        mismatch = check_code(
            levels,
            level_sig,
            lit,
            off,
            on_ratio=config.on_ratio,
            off_ratio=config.off_ratio,
            level_sigma=config.level_sigma,
        )
        if mismatch:
            reasons.append(RejectReason.CODE_MISMATCH)
            why.append(f"code {seq.code(led)}: {mismatch}")
        if snr < config.min_snr:
            reasons.append(RejectReason.LOW_SNR)
            why.append(f"snr {snr:.1f} < min_snr {config.min_snr:g}")
        saturated = bool(prep.saturated[lit][:, box[0], box[1]][:, window].any())
        out.append(
            _Candidate(
                led=led,
                pixel=pixel,
                sigma_px=sigma_px,
                area=area,
                peak=peak,
                snr=snr,
                levels=levels * float(template.max()),
                reasons=tuple(reasons),
                message="; ".join(why),
                box=box,
                window=window,
                saturated=saturated,
                roundness=roundness(sig, window),
            )
        )
    return out, note


# -- classification -------------------------------------------------------------------------
def _fmt(p: NDArray[np.float64] | tuple[float, float]) -> str:
    return f"({p[0]:.1f}, {p[1]:.1f})"


def _classify(
    prep: _Prepared,
    seq: SwitchingSequence,
    candidates: list[list[_Candidate]],
    line: NDArray[np.float64] | None,
    config: DetectorConfig,
) -> list[LedDetection]:
    shape = prep.reference.shape
    accepted = [[c for c in cands if not c.reasons] for cands in candidates]
    found = {led: acc[0] for led, acc in enumerate(accepted) if len(acc) == 1}
    # Pixels of accepted candidates of every LED: no faint search there.
    taken = np.zeros(shape, bool)
    for acc in accepted:
        for c in acc:
            taken[c.box] |= c.window
    partial = _partly_hidden(found, config)
    out = []
    for led in range(seq.n_leds):
        code = seq.code(led)
        if led in partial:
            c = found[led]
            out.append(
                LedDetection(
                    led,
                    peak=c.peak,
                    area=c.area,
                    snr=c.snr,
                    failure=DetectionFailure.PARTIAL,
                    message=f"code {code}: found at {_fmt(c.pixel)} but {partial[led]}; "
                    "its centroid would be biased, so it is not used",
                )
            )
            continue
        if led in found:
            c = found[led]
            note = (
                "saturated pixels in its lit frames; the centroid may be biased"
                if c.saturated
                else ""
            )
            out.append(LedDetection(led, c.pixel, c.peak, c.area, c.snr, c.sigma_px, None, note))
            continue
        failure, message = _why_missing(prep, seq, led, candidates, accepted, taken, line, config)
        out.append(LedDetection(led, failure=failure, message=f"code {code}: {message}"))
    return out


def _partly_hidden(found: dict[int, _Candidate], config: DetectorConfig) -> dict[int, str]:
    """The found LEDs whose spot looks cut (partly hidden), with the evidence.

    An LED's image is a disc. A spot that is (a) elongated (roundness below
    ``partial_roundness``, lowered for spots under ``partial_full_area_px``; judged for
    spots of at least ``partial_min_area_px`` and ``partial_min_snr``) or (b) much smaller
    than the assembly's other LEDs (area below ``partial_area_ratio`` of their median, if
    that is at least ``partial_min_area_px``: they are all at about the same distance) is
    partly hidden: its centroid is pulled away from the LED's centre, by up to a spot's
    radius. (Where a spot lies on the mast's image line is no test: lens distortion bends
    that line by more than a cut moves the centroid, 0.8 px near a corner of the paper's
    camera 1.)
    """
    out: dict[int, str] = {}
    for led, c in found.items():
        others = [o for k, o in found.items() if k != led]
        limit = config.partial_roundness * min(1.0, c.area / config.partial_full_area_px)
        if (
            c.area >= config.partial_min_area_px
            and c.snr >= config.partial_min_snr
            and c.roundness < limit
        ):
            out[led] = (
                f"its spot is elongated (roundness {c.roundness:.2f} < {limit:.2f} for "
                f"{c.area} px): partly hidden"
            )
        elif len(others) >= 2:
            median = float(np.median([o.area for o in others]))
            if median >= config.partial_min_area_px and c.area < config.partial_area_ratio * median:
                out[led] = (
                    f"its spot ({c.area} px) is much smaller than the other LEDs' "
                    f"({median:.0f} px): partly hidden"
                )
    return out


def _why_missing(
    prep: _Prepared,
    seq: SwitchingSequence,
    led: int,
    candidates: list[list[_Candidate]],
    accepted: list[list[_Candidate]],
    taken: NDArray[np.bool_],
    line: NDArray[np.float64] | None,
    config: DetectorConfig,
) -> tuple[DetectionFailure, str]:
    mine = candidates[led]
    if len(accepted[led]) > 1:
        where = ", ".join(f"{_fmt(c.pixel)} snr {c.snr:.0f}" for c in accepted[led])
        return DetectionFailure.AMBIGUOUS, (
            f"{len(accepted[led])} candidates follow this code: {where}; "
            "cannot tell which is the LED"
        )
    scene = [c for c in mine if c.reasons == (RejectReason.SCENE_CHANGED,)]
    if scene:
        return DetectionFailure.SCENE_CHANGED, (
            f"a candidate at {_fmt(scene[0].pixel)} follows the code, but the scene changed "
            "there between the dark frames (someone or something moved); not used"
        )
    # Faint response: look everywhere except accepted LEDs, changed regions and candidates
    # rejected for a reason other than low SNR.
    exclude = taken | prep.changed
    for c in mine:
        if c.reasons != (RejectReason.LOW_SNR,):
            exclude[c.box] |= c.window
    lit = seq.pattern[:, led]
    off = seq.pattern.any(axis=1) & ~lit
    matched, matched_var, _, _ = _matched(prep, lit, off)
    faint = find_faint(
        matched,
        matched_var,
        prep.comp - prep.reference,
        prep.var + prep.var_ref,
        lit,
        off,
        exclude,
        smooth_px=config.faint_smooth_px,
        z_min=config.faint_sigma,
        on_ratio=config.on_ratio,
        off_ratio=config.off_ratio,
        level_sigma=config.level_sigma,
    )
    if faint is not None:
        return DetectionFailure.TOO_FAINT, (
            f"a response near {_fmt(faint.pixel)} follows the code at {faint.z:.1f} sigma "
            f"after smoothing, but is below the detection level ({config.threshold_sigma:g} "
            f"sigma per pixel, snr {config.min_snr:g}); make the LED brighter or the "
            "exposure longer"
        )
    border = [
        c
        for c in mine
        if RejectReason.AT_BORDER in c.reasons
        and RejectReason.CODE_MISMATCH not in c.reasons
        and RejectReason.TOO_LARGE not in c.reasons
    ]
    if border:
        return DetectionFailure.NOT_IN_VIEW, (
            f"a candidate at {_fmt(border[0].pixel)} follows the code but touches the image "
            "border; the LED is cut by it"
        )
    h, w = prep.reference.shape
    moved = [c for c in mine if RejectReason.SCENE_CHANGED in c.reasons]
    if moved:
        unknown = (
            DetectionFailure.SCENE_CHANGED,
            f"nothing found, and something moved in the view between the dark frames (a "
            f"candidate at {_fmt(moved[0].pixel)} overlaps the change); it may hide the LED: "
            "capture again",
        )
    else:
        unknown = (DetectionFailure.NOT_FOUND, "nothing found; out of view or hidden")
    if line is None:
        failure, message = unknown
        if failure == DetectionFailure.NOT_FOUND:
            message += " (give led_line to tell which)"
        return failure, message
    others = [k for k in range(seq.n_leds) if k != led and len(accepted[k]) == 1]  # found LEDs
    if len(others) < MIN_LINE_LEDS:
        return unknown[0], (
            f"{unknown[1]} (only {len(others)} other LEDs found, {MIN_LINE_LEDS} needed to "
            "predict its place on the line)"
        )
    pixels = np.array([accepted[k][0].pixel for k in others])
    pred = predict_on_line(line[others], pixels, float(line[led]))
    if pred.residual_px > config.line_tolerance_px:
        return unknown[0], (
            f"{unknown[1]} (the found LEDs are up to {pred.residual_px:.1f} px off a straight "
            f"line, more than line_tolerance_px {config.line_tolerance_px:g}, so its place "
            "cannot be predicted)"
        )
    if pred.pixel is None:
        return DetectionFailure.NOT_IN_VIEW, (
            "the other LEDs on its line put it beyond the line's vanishing point"
        )
    if not inside_image(pred.pixel, (h, w)):
        return DetectionFailure.NOT_IN_VIEW, (
            f"the other LEDs on its line put it at {_fmt(pred.pixel)}, outside the {w}x{h} image"
        )
    r = min(max(round(float(pred.pixel[1])), 0), h - 1)
    col = min(max(round(float(pred.pixel[0])), 0), w - 1)
    if prep.changed[r, col]:
        return DetectionFailure.SCENE_CHANGED, (
            f"the other LEDs on its line put it at {_fmt(pred.pixel)}, where the scene changed "
            "between the dark frames (someone or something moved there): capture again"
        )
    return DetectionFailure.OCCLUDED, (
        f"the other LEDs on its line put it at {_fmt(pred.pixel)} inside the image, but "
        "nothing there follows its code; hidden"
    )


def _rejected(
    candidates: list[list[_Candidate]], seq: SwitchingSequence, shape: tuple[int, ...]
) -> list[RejectedCandidate]:
    """The rejected candidates, less those that are another LED's accepted light."""
    owner = np.full(shape, -1, dtype=int)
    for cands in candidates:
        for c in cands:
            if not c.reasons:
                owner[c.box][c.window] = c.led
    out = []
    for cands in candidates:
        for c in cands:
            if not c.reasons:
                continue
            r = min(max(round(float(c.pixel[1])), 0), shape[0] - 1)
            col = min(max(round(float(c.pixel[0])), 0), shape[1] - 1)
            other = owner[r, col]
            if c.reasons == (RejectReason.CODE_MISMATCH,) and other not in (-1, c.led):
                continue
            out.append(
                RejectedCandidate(
                    led=c.led,
                    code=seq.code(c.led),
                    pixel=c.pixel,
                    area=c.area,
                    peak=c.peak,
                    levels=c.levels,
                    reasons=c.reasons,
                    message=c.message,
                )
            )
    return out
