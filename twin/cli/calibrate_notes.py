"""The notes of ``twin calibrate``: a result's notes, told in terms of its options.

The library states what is implausible about a calibration (:mod:`calib.plausibility`);
here each finding gets the option that most likely fixes it (``--units``, ``--image-size``),
and warnings that the calibration emitted without a note (a nearly coplanar point cloud)
join the notes, so that nothing a user should read is lost.
"""

from __future__ import annotations

import warnings

from calib import CalibrationResult
from calib.plausibility import Implausibility

DEFAULT_UNITS = "m"
UNIT_NAMES = {"m": "metres", "mm": "millimetres"}


_UNIT_FIXES = {
    ("units-too-large", "m"): "if the file is in millimetres, run again with --units mm",
    ("units-too-large", "mm"): "the file's unit looks smaller than millimetres: convert it",
    ("units-too-small", "mm"): "if the file is in metres, run again without --units mm",
    ("units-too-small", "m"): "the file's unit looks larger than metres: convert it",
}


def implausible_note(finding: Implausibility, units: str) -> str:
    """One finding as ``twin calibrate`` prints it, naming the option to check.

    Args:
        finding: what is implausible (see :mod:`calib.plausibility`).
        units: the ``--units`` the file was read with.
    """
    if finding.cause == "image":
        return (
            f"{finding.finding}: check --image-size (the size of the image the pixels were "
            "measured in), that u,v are in pixels, and that each row's point and pixel belong "
            "together"
        )
    size = "large" if finding.cause == "units-too-large" else "small"
    default = ", the default" if units == DEFAULT_UNITS else ""
    return (
        f"{finding.finding}: the lengths look 1000 times too {size}; x,y,z were read in "
        f"{UNIT_NAMES[units]} (--units {units}{default}): "
        f"{_UNIT_FIXES[finding.cause, units]}"
    )


def cli_notes(
    result: CalibrationResult, units: str, caught: list[warnings.WarningMessage]
) -> tuple[list[str], list[str]]:
    """The notes and warnings of a calibration as ``twin calibrate`` reports them.

    Args:
        result: the calibration.
        units: the ``--units`` the file was read with.
        caught: the warnings recorded while calibrating; those whose message is not among
            the result's notes are added to the notes.

    Returns:
        notes (every message, in order) and warnings (those of them that point to a likely
        mistake in the input, each naming the option to check).
    """
    told = {f.note: implausible_note(f, units) for f in result.implausible}
    notes = [told.get(n, n) for n in result.notes]
    for w in caught:
        message = str(w.message)
        if message not in result.notes and message not in notes:
            notes.append(message)
    return notes, list(told.values())


def _v_fix(pixel_origin: str) -> str:
    """The option that turns the pixels' v the other way, given the current origin."""
    if pixel_origin == "bottom-left":
        return "run again without --pixel-origin bottom-left (v counted from the top)"
    return "run again with --pixel-origin bottom-left (v counted from the bottom)"


def mirrored_message(
    problem: str, hints: tuple[str, ...], rms_px: float, mirror_axis: str | None, pixel_origin: str
) -> str:
    """The error for points that fit only in their mirror image, naming the option to use.

    Args:
        problem: what went wrong with the points as given (the calibration's error, or the
            poor fit).
        hints: the likely causes (:func:`calib.handedness.mirror_hints`).
        rms_px: pixel residual RMS of the mirrored fit, px.
        mirror_axis: the ``--mirror-axis`` already given, or None.
        pixel_origin: the ``--pixel-origin`` given.
    """
    fits = (
        f"{problem}; but the points fit a camera in their mirror image (pixel RMS {rms_px:.3g} px)"
    )
    if mirror_axis is not None:
        return (
            f"{fits}, that is without --mirror-axis {mirror_axis}: the frame appears "
            "right-handed; run again without --mirror-axis"
        )
    if hints == ("x", "y", "v"):
        cause = (
            "the world frame appears mirrored (left-handed): the fitted camera sits above its "
            "points, so z is up and the x or the y axis is reversed. The data cannot tell which "
            "(negating either gives the same camera in your frame): run again with "
            "--mirror-axis x or --mirror-axis y, the axis your survey reversed. If instead "
            f"the pixels' v is counted the other way, {_v_fix(pixel_origin)}"
        )
    elif hints == ("z",):
        cause = (
            "the world frame appears mirrored (left-handed): the fitted camera sits below its "
            "points, so the z axis appears reversed (pointing down): run again with "
            "--mirror-axis z"
        )
    else:
        cause = (
            "the world frame appears mirrored (left-handed), and the scene does not tell which "
            "axis is reversed (any gives the same camera in your frame): run again with "
            "--mirror-axis x, y or z. If instead the pixels' v is counted the other way, "
            f"{_v_fix(pixel_origin)}"
        )
    return f"{fits}: {cause}"


def mirror_note(axis: str) -> str:
    """The note of a calibration run with ``--mirror-axis``."""
    return (
        f"--mirror-axis {axis}: the points' {axis} was negated to make the frame right-handed; "
        "the position and the camera axes are given in your frame; the rotation and the "
        f"camera written by --out describe the camera in the mirrored frame ({axis} negated)"
    )
