"""Magnitudes that no real calibration produces, and the input mistake they point to.

A perspective camera cannot tell a scene from a scaled copy of it. A file in millimetres
read as metres calibrates without any error: the pixels, the residuals and the focal
length come out the same, and the camera and every length 1000 times too large (the
example of docs/calibration.md, in millimetres, puts the camera 5 km from its points with a
3D error of 3.5 m). Only absolute magnitudes can tell, so a finished calibration is checked against
these bounds:

* Range: the median distance from the optical centre to the points must lie within
  [``MIN_RANGE_M``, ``MAX_RANGE_M``] = [5 cm, 1 km]. Reading a file in the wrong unit
  scales every length by 1000 (millimetres read as metres) or 1/1000 (metres read as
  millimetres). The bounds are 20,000 apart, wider than that factor, so every scene whose
  true range lies in [1 m, 50 m] is flagged when read in the wrong unit (1 m becomes 1 km;
  50 m becomes 5 cm), the band of cameras watching robots' LEDs (the paper's at 3-15 m).
  A scene read in its right unit is flagged only beyond the bounds, where a real one
  hardly exists: at 1 km one pixel of a lens with f = 1000 px spans a metre, so LEDs or
  targets of centimetres would be far below a pixel; nearer than 5 cm is inside the
  close-focus distance of every lens but a macro lens.
* Field of view: the field of view across the image diagonal, 2 atan(d / 2f) with d the
  diagonal in pixels (sx applied), must lie within [``MIN_FOV_DEG``, ``MAX_FOV_DEG``] =
  [0.5 deg, 160 deg]. Rectilinear lenses span about 1 deg (long telephoto) to 120 deg (the
  widest), and Tsai's single radial term cannot fit a fisheye beyond them; the bounds lie
  a factor of 2 and 40 deg outside, so only a focal length far outside what the image size
  makes plausible is flagged: pixel coordinates not in pixels of an image of this size
  (normalised, in millimetres on the sensor, from another resolution), or points and
  pixels that do not pair up.
* Distortion (Tsai's model): kappa1 r^2 at the image corner, the relative change of radius
  that the lens would make there, must stay within ``MAX_CORNER_DISTORTION`` = 2 in size.
  Strong wide-angle lenses change the corner radius by tens of percent (kappa1 r^2 about
  0.3); a change of 200% is a fisheye that one radial term cannot represent. Beyond it the
  fit has bent the model to fit pixels that are not pixels of this image (coordinates in
  millimetres on the sensor crowd into a corner of a few pixels).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

MIN_RANGE_M = 0.05
MAX_RANGE_M = 1000.0
MIN_FOV_DEG = 0.5
MAX_FOV_DEG = 160.0
MAX_CORNER_DISTORTION = 2.0


@dataclass(frozen=True)
class Implausibility:
    """A magnitude no real calibration produces.

    Attributes:
        finding: what is implausible, with the numbers (SI units).
        cause: "units-too-large" (lengths 1000 times too large: millimetres read as
            metres), "units-too-small" (metres read as millimetres) or "image" (pixels
            that do not belong to an image of the given size, or wrong pairing).
        advice: the likely mistake, in terms of the library's inputs.
    """

    finding: str
    cause: str
    advice: str

    @property
    def note(self) -> str:
        """The note a calibration result carries: the finding and the advice."""
        return f"{self.finding}: {self.advice}"


def _length(metres: float) -> str:
    if metres >= 1000.0:
        return f"{metres / 1000.0:.3g} km"
    if metres >= 1.0:
        return f"{metres:.3g} m"
    return f"{metres * 1000.0:.3g} mm"


def field_of_view_deg(f_px: float, sx: float, image_size: tuple[int, int]) -> float:
    """Field of view across the image diagonal of a pinhole camera, deg.

    Args:
        f_px: focal length, px (pixel heights). sx: horizontal scale factor.
        image_size: (width, height), px.
    """
    w, h = image_size
    half_diagonal = 0.5 * np.hypot(w / sx, h)
    return float(np.degrees(2.0 * np.arctan2(half_diagonal, f_px)))


def check_magnitudes(
    position: NDArray[np.float64],
    f_px: float,
    sx: float,
    image_size: tuple[int, int],
    points_3d: NDArray[np.float64],
    kappa1: float | None = None,
) -> list[Implausibility]:
    """The implausible magnitudes of a calibrated camera on its points (see the module).

    Args:
        position: (3,) optical centre in the world, m.
        f_px: focal length, px. sx: horizontal scale factor.
        image_size: (width, height), px.
        points_3d: (N, 3) the calibration points, m.
        kappa1: Tsai's radial distortion, 1/px^2 (None for other models: not checked).

    Returns:
        The findings, at most one per bound; empty for a plausible calibration.
    """
    found = []
    dist = float(np.median(np.linalg.norm(points_3d - position, axis=1)))
    span = float(np.linalg.norm(np.ptp(points_3d, axis=0)))
    where = (
        f"the camera is {_length(dist)} from its points (median distance; they span "
        f"{_length(span)})"
    )
    if dist > MAX_RANGE_M:
        found.append(
            Implausibility(
                f"{where}, beyond the {_length(MAX_RANGE_M)} within which cameras are "
                "calibrated from points",
                "units-too-large",
                "the lengths look 1000 times too large: were the coordinates in millimetres?",
            )
        )
    elif dist < MIN_RANGE_M:
        found.append(
            Implausibility(
                f"{where}, nearer than the {_length(MIN_RANGE_M)} within which no camera is "
                "calibrated from points",
                "units-too-small",
                "the lengths look 1000 times too small: were the coordinates in metres taken "
                "as millimetres?",
            )
        )
    fov = field_of_view_deg(f_px, sx, image_size)
    if not MIN_FOV_DEG <= fov <= MAX_FOV_DEG:
        w, h = image_size
        found.append(
            Implausibility(
                f"the focal length of {f_px:.4g} px gives the {w}x{h} image a field of view "
                f"of {fov:.3g} deg, outside the {MIN_FOV_DEG:g}-{MAX_FOV_DEG:g} deg of real "
                "lenses",
                "image",
                "are the pixels in pixels of an image of this size, and do the points and "
                "pixels pair up?",
            )
        )
    if kappa1 is not None:
        w, h = image_size
        corner = kappa1 * ((w / 2.0 / sx) ** 2 + (h / 2.0) ** 2)
        if abs(corner) > MAX_CORNER_DISTORTION:
            found.append(
                Implausibility(
                    f"kappa1 = {kappa1:.3g} 1/px^2 changes the radius at the corner of the "
                    f"{w}x{h} image by {100 * corner:.3g}%, beyond the "
                    f"{100 * MAX_CORNER_DISTORTION:.0f}% of any lens this model represents",
                    "image",
                    "are the pixels in pixels of an image of this size, and do the points "
                    "and pixels pair up?",
                )
            )
    return found
