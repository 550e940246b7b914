"""What the LED detector returns: one record per LED, the rejected candidates, diagnostics."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np
from numpy.typing import NDArray

from calib.detection.noise import NoiseModel


class DetectionFailure(StrEnum):
    """Why an LED has no image position. The detector never replaces it with a guess."""

    NOT_IN_VIEW = "not_in_view"  # outside the image, or cut by its border
    OCCLUDED = "occluded"  # inside the image (by the other LEDs' line) but no response
    TOO_FAINT = "too_faint"  # a consistent response, below the detection level
    AMBIGUOUS = "ambiguous"  # more than one candidate matches the LED's code
    SCENE_CHANGED = "scene_changed"  # a match, but the scene changed there (someone moved)
    NOT_FOUND = "not_found"  # nothing found; out of view or hidden
    PARTIAL = "partial"  # found, but its spot is cut (partly hidden): centroid biased


class RejectReason(StrEnum):
    """Why a candidate blob is not an LED."""

    TOO_LARGE = "too_large"  # larger than DetectorConfig.max_area_px
    AT_BORDER = "at_border"  # touches the image border: may be cut, centroid biased
    SCENE_CHANGED = "scene_changed"  # overlaps pixels that changed between dark frames
    CODE_MISMATCH = "code_mismatch"  # its per-frame levels do not follow the LED's code
    LOW_SNR = "low_snr"  # above threshold, but flux SNR below DetectorConfig.min_snr


@dataclass(frozen=True, eq=False)
class RejectedCandidate:
    """A blob of an LED's code-matched difference image that was not accepted as the LED.

    Attributes:
        led: the LED whose code was tried.
        code: that LED's code over the code frames, e.g. "1100".
        pixel: (2,) intensity-weighted centroid (u, v), px.
        area: pixels above the threshold.
        peak: largest value of the code-matched difference, DN.
        levels: (n_frames,) the blob's level in every frame against the reference, DN.
        reasons: every check it failed.
        message: the failed checks in words, with their numbers.
    """

    led: int
    code: str
    pixel: NDArray[np.float64]
    area: int
    peak: float
    levels: NDArray[np.float64]
    reasons: tuple[RejectReason, ...]
    message: str


@dataclass(frozen=True, eq=False)
class LedDetection:
    """The image position of one LED, or why there is none.

    Attributes:
        led: LED index (column of the switching pattern).
        pixel: (2,) sub-pixel position (u, v) = (column, row), px, OpenCV convention
            ((0, 0) is the centre of the top-left pixel); None when ``failure`` is set.
        peak: largest value of the code-matched difference (LED brightness above the
            background), DN; NaN if not found.
        area: pixels above the threshold; 0 if not found.
        snr: flux signal-to-noise ratio over the centroid window; NaN if not found.
        sigma_px: predicted standard deviation of each centroid coordinate from the noise
            model, px; NaN if not found. Sensor noise only: how the spot was sampled (a
            small disc on the pixel grid, the lens, the renderer's antialiasing) adds a
            bias that does not scatter, measured 0.02-0.08 px on the twin's images.
        failure: why there is no position; None when found.
        message: the failure in words (with candidate positions or the predicted place), or
            notes on a found LED (saturation); "" if none.
    """

    led: int
    pixel: NDArray[np.float64] | None = None
    peak: float = float("nan")
    area: int = 0
    snr: float = float("nan")
    sigma_px: float = float("nan")
    failure: DetectionFailure | None = None
    message: str = ""

    def __post_init__(self) -> None:
        if (self.pixel is None) == (self.failure is None):
            raise ValueError(
                f"LED {self.led}: exactly one of pixel and failure must be set, got "
                f"pixel={self.pixel}, failure={self.failure}"
            )
        if self.pixel is not None:
            p = np.array(self.pixel, dtype=float).reshape(2)
            p.setflags(write=False)
            object.__setattr__(self, "pixel", p)

    @property
    def found(self) -> bool:
        """True when the LED has an image position."""
        return self.failure is None


@dataclass(frozen=True, eq=False)
class LedDetections:
    """The result of one detection sequence.

    Attributes:
        leds: one LedDetection per LED, index = LED.
        noise: the noise model used (given or estimated from the dark frames).
        frame_gains: (n_frames,) light level of each frame relative to the dark reference
            (1 = unchanged); all 1 when gain compensation is off.
        rejected: candidates that were not accepted, with their reasons.
        changed_fraction: fraction of the pixels that changed between the dark frames.
        light_changed: some frame's light level differs by more than the gain tolerance.
        messages: notes on the whole sequence (light changes, scene changes, input).
    """

    leds: tuple[LedDetection, ...]
    noise: NoiseModel
    frame_gains: NDArray[np.float64]
    rejected: tuple[RejectedCandidate, ...] = ()
    changed_fraction: float = 0.0
    light_changed: bool = False
    messages: tuple[str, ...] = ()

    @property
    def n_leds(self) -> int:
        """Number of LEDs."""
        return len(self.leds)

    def pixels(self) -> NDArray[np.float64]:
        """(n_leds, 2) positions (u, v), px; NaN rows for LEDs that were not found."""
        out = np.full((self.n_leds, 2), np.nan)
        for d in self.leds:
            if d.pixel is not None:
                out[d.led] = d.pixel
        return out

    @property
    def found(self) -> NDArray[np.bool_]:
        """(n_leds,) True where the LED was found."""
        return np.array([d.found for d in self.leds], dtype=bool)

    def sigmas(self) -> NDArray[np.float64]:
        """(n_leds,) predicted centroid standard deviation per coordinate, px (NaN: missing)."""
        return np.array([d.sigma_px for d in self.leds])

    def failures(self) -> dict[int, DetectionFailure]:
        """The LEDs that were not found, with the reason."""
        return {d.led: d.failure for d in self.leds if d.failure is not None}

    def summary(self) -> str:
        """One line per LED: its position and quality, or its failure and message."""
        lines = []
        for d in self.leds:
            if d.pixel is not None:
                lines.append(
                    f"LED {d.led}: ({d.pixel[0]:.2f}, {d.pixel[1]:.2f}) px, peak {d.peak:.1f} DN,"
                    f" area {d.area} px, snr {d.snr:.1f}, sigma {d.sigma_px:.3f} px"
                )
            else:
                lines.append(f"LED {d.led}: {d.failure}: {d.message}")
        return "\n".join(lines + list(self.messages))
