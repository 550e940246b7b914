"""What the candidates say of each LED: found, partly hidden, or why it was not found
(AMBIGUOUS, SCENE_CHANGED, TOO_FAINT, NOT_IN_VIEW, OCCLUDED, NOT_FOUND), and which rejected
candidates to report."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from calib.detection.candidates import Candidate, Prepared, matched_difference
from calib.detection.classify import find_faint, inside_image, predict_on_line
from calib.detection.config import DetectorConfig
from calib.detection.results import (
    DetectionFailure,
    LedDetection,
    RejectedCandidate,
    RejectReason,
)
from calib.detection.sequence import SwitchingSequence

MIN_LINE_LEDS = 3  # found LEDs needed to predict a missing one's place on the mast


def _fmt(p: NDArray[np.float64] | tuple[float, float]) -> str:
    return f"({p[0]:.1f}, {p[1]:.1f})"


def classify_leds(
    prep: Prepared,
    seq: SwitchingSequence,
    candidates: list[list[Candidate]],
    line: NDArray[np.float64] | None,
    config: DetectorConfig,
) -> list[LedDetection]:
    """One detection per LED: found (exactly one accepted candidate), partly hidden, or
    the reason it was not found (step 6 of :mod:`calib.detection.detector`)."""
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


def _partly_hidden(found: dict[int, Candidate], config: DetectorConfig) -> dict[int, str]:
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
    prep: Prepared,
    seq: SwitchingSequence,
    led: int,
    candidates: list[list[Candidate]],
    accepted: list[list[Candidate]],
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
    matched, matched_var, _, _ = matched_difference(prep, lit, off)
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


def rejected_candidates(
    candidates: list[list[Candidate]], seq: SwitchingSequence, shape: tuple[int, ...]
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
