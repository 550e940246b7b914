"""The candidates of an LED: the components of its code-matched difference image, each
measured (sub-pixel centroid, size, SNR, per-frame levels) and checked against the LED's
code and the detector's limits."""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from calib.detection.blobs import centroid, check_code, dilate, frame_levels, roundness
from calib.detection.config import DetectorConfig
from calib.detection.results import RejectReason
from calib.detection.sequence import SwitchingSequence

MAX_CANDIDATES = 200  # components measured per LED (the brightest); more are only counted


@dataclass(frozen=True, eq=False)
class Candidate:
    """A component of one LED's code-matched difference image, measured and judged: its
    centroid (px) with its standard deviation, size, peak, SNR, per-frame levels, and the
    reasons it is rejected (none: accepted)."""

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
class Prepared:
    """Frames after gain compensation, with their noise."""

    comp: NDArray[np.float64]  # (n, H, W) gain-compensated frames, DN
    var: NDArray[np.float64]  # (n, H, W) their variances, DN^2
    reference: NDArray[np.float64]  # (H, W) mean of the dark frames
    var_ref: NDArray[np.float64]  # (H, W) its variance
    saturated: NDArray[np.bool_]  # (n, H, W)
    changed: NDArray[np.bool_]  # (H, W) changed between dark frames, dilated


def matched_difference(
    prep: Prepared, lit: NDArray[np.bool_], off: NDArray[np.bool_]
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


def measure_candidates(
    prep: Prepared, seq: SwitchingSequence, led: int, config: DetectorConfig
) -> tuple[list[Candidate], str | None]:
    """The candidates of one LED (at most ``MAX_CANDIDATES``, the brightest), each checked
    (steps 3 to 5 of :mod:`calib.detection.detector`), and a note if some were left out."""
    lit = seq.pattern[:, led]
    code = seq.pattern.any(axis=1)
    off = code & ~lit
    matched, matched_var, base, var_base = matched_difference(prep, lit, off)
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
            Candidate(
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
