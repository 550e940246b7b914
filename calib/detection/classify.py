"""Why an LED was not found: faint responses and the place the other LEDs predict for it.

The LEDs of a child robot sit on one straight mast. Under perspective a straight line maps
to a straight image line, and positions along it by a 1-D projective map (it keeps the
cross-ratio): s = (a t + b) / (c t + 1), t the LED's position along the mast (m), s its
position along the image line (px). Three found LEDs fix the map, and so the image place of
a missing one: outside the image means NOT_IN_VIEW, inside with no response OCCLUDED. The
predicted place is used only for that decision, never as a measurement.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from calib.detection.blobs import check_code, frame_levels


@dataclass(frozen=True, eq=False)
class LinePrediction:
    """The image place of a missing LED predicted from the others on its line.

    Attributes:
        pixel: (2,) predicted (u, v), px; None if the LED lies beyond the line's vanishing
            point (behind the camera's view of the line).
        residual_px: largest distance of the found LEDs from their fitted image line, px.
    """

    pixel: NDArray[np.float64] | None
    residual_px: float


def predict_on_line(
    positions: NDArray[np.float64],
    pixels: NDArray[np.float64],
    query: float,
) -> LinePrediction:
    """Predict the image of the point at ``query`` on a 3-D line from imaged points on it.

    Args:
        positions: (k,) k >= 3 distinct positions along the line, m.
        pixels: (k, 2) their image positions (u, v), px.
        query: the position whose image is wanted, m.

    Returns:
        The prediction and how far the found points are from a straight image line.
    """
    t = np.asarray(positions, dtype=float)
    p = np.asarray(pixels, dtype=float)
    if t.shape[0] < 3 or p.shape != (t.shape[0], 2):
        raise ValueError(
            f"line prediction needs k >= 3 positions and (k, 2) pixels, got {t.shape} and {p.shape}"
        )
    centre = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - centre)
    direction = vt[0]
    s = (p - centre) @ direction
    residual = float(np.max(np.abs((p - centre) @ vt[1])))
    # Normalise both coordinates for a well-conditioned linear fit of (a, b, c) in
    # s (c t + 1) = a t + b.
    t0, ts = t.mean(), max(float(np.ptp(t)), 1e-12)
    ss = max(float(np.ptp(s)), 1e-12)
    tn, sn, qn = (t - t0) / ts, s / ss, (query - t0) / ts
    design = np.column_stack([tn, np.ones_like(tn), -tn * sn])
    (a, b, c), *_ = np.linalg.lstsq(design, sn, rcond=None)
    den = c * tn + 1.0
    den_q = c * qn + 1.0
    if np.abs(den_q) < 1e-9 or np.sign(den_q) != np.sign(np.median(den)):
        return LinePrediction(None, residual)
    s_q = (a * qn + b) / den_q * ss
    return LinePrediction(centre + s_q * direction, residual)


def inside_image(pixel: NDArray[np.float64], shape: tuple[int, int]) -> bool:
    """Whether (u, v) lies on an image of ``shape`` (H, W): [-0.5, W - 0.5] x [-0.5, H - 0.5]."""
    h, w = shape
    return bool(-0.5 <= pixel[0] <= w - 0.5 and -0.5 <= pixel[1] <= h - 0.5)


@dataclass(frozen=True)
class FaintResponse:
    """A code-consistent response below the detection level.

    Attributes:
        pixel: (u, v) of the smoothed maximum, px (for the message only).
        z: its smoothed signal-to-noise ratio.
    """

    pixel: tuple[float, float]
    z: float


def find_faint(
    matched: NDArray[np.float64],
    matched_var: NDArray[np.float64],
    diffs: NDArray[np.float64],
    diff_vars: NDArray[np.float64],
    lit: NDArray[np.bool_],
    off: NDArray[np.bool_],
    exclude: NDArray[np.bool_],
    *,
    smooth_px: float,
    z_min: float,
    on_ratio: float,
    off_ratio: float,
    level_sigma: float,
    max_tries: int = 5,
) -> FaintResponse | None:
    """Look for a response of an LED's code that is significant only after smoothing.

    The code-matched image is smoothed with a Gaussian of ``smooth_px`` (a matched filter
    for a small spot) and divided by the smoothed noise; at the highest maxima above
    ``z_min`` outside ``exclude``, the levels of the Gaussian template in every frame must
    follow the code (:func:`check_code`). A single noisy pixel is shrunk by the smoothing
    (by 0.56 for 1 px) and does not trigger it.

    Args:
        matched: (H, W) code-matched difference image, DN. matched_var: its variance.
        diffs: (n, H, W) frame differences from the reference; diff_vars: their variances.
        lit, off: (n,) bool frames where the LED is lit / must be off.
        exclude: (H, W) bool pixels not to look at (candidates, changed regions).

    Returns:
        The strongest consistent response, or None.
    """
    radius = max(1, int(np.ceil(3.0 * smooth_px)))
    size = 2 * radius + 1
    g1 = cv2.getGaussianKernel(size, smooth_px).ravel()
    kernel = np.outer(g1, g1)
    num = cv2.filter2D(matched, cv2.CV_64F, kernel, borderType=cv2.BORDER_CONSTANT)
    den = cv2.filter2D(matched_var, cv2.CV_64F, kernel * kernel, borderType=cv2.BORDER_CONSTANT)
    z = num / np.sqrt(np.maximum(den, 1e-300))
    z[exclude] = 0.0
    h, w = matched.shape
    # Only maxima whose template fits inside the image.
    z[:radius] = z[h - radius :] = 0.0
    z[:, :radius] = z[:, w - radius :] = 0.0
    above = (z >= z_min).astype(np.uint8)
    if not above.any():
        return None
    n, labels = cv2.connectedComponents(above, connectivity=8)
    index = np.arange(1, n)
    places = ndimage.maximum_position(z, labels, index)
    values = ndimage.maximum(z, labels, index)
    peaks = sorted(
        ((float(v), (int(r), int(c))) for v, (r, c) in zip(values, places, strict=True)),
        reverse=True,
    )
    for zval, (r, c) in peaks[:max_tries]:
        sl = np.s_[r - radius : r + radius + 1, c - radius : c + radius + 1]
        levels, sigmas = frame_levels(diffs[:, sl[0], sl[1]], diff_vars[:, sl[0], sl[1]], kernel)
        why = check_code(
            levels,
            sigmas,
            lit,
            off,
            on_ratio=on_ratio,
            off_ratio=off_ratio,
            level_sigma=level_sigma,
        )
        if why is None:
            return FaintResponse((float(c), float(r)), zval)
    return None
