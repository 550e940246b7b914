"""Settings of the LED detector, with the reasons for their defaults."""

from __future__ import annotations

import math
from dataclasses import dataclass

from calib.detection.frames import CHANNELS, COLOR_ORDERS


@dataclass(frozen=True)
class DetectorConfig:
    """Settings of :func:`calib.detection.detect_leds`.

    Thresholds are in standard deviations of the noise, so they hold for any camera and
    exposure once the noise is known; only the areas and the noise floor are in pixels/DN.

    Attributes:
        threshold_sigma: a pixel of an LED's code-matched difference image belongs to a
            candidate when it exceeds this many sigma. 5: about 3e-7 false pixels per pixel,
            0.02 per 320 x 240 image per LED; such single noise pixels then fail min_snr.
        min_snr: smallest flux signal-to-noise ratio of an accepted candidate (flux summed
            over the centroid window / its standard deviation). 5: a single noise pixel at
            5 sigma in a 3 x 3 window reaches only about 5/3; at snr 5 a small spot's centroid
            is good to about 0.3 px.
        max_area_px: largest area above threshold of an LED, px. 400: a disc of 22 px
            diameter, twice the 10 px an LED of 4 cm makes at 3 m with f = 770 px, so LEDs
            down to 1.5 m pass while people, doors and light patches do not.
        dilate_px: the centroid window is the candidate dilated by this many pixels, to take
            in the wings of the spot that are below the threshold. 2: the wings of a blurred
            spot reach about 2.5 sigma_psf beyond the 5-sigma contour of a bright spot; more
            only adds noise.
        channel: how colour frames become one channel: "gray" (mean of the channels),
            "red", "green", "blue" or "max". An LED of one colour is best seen in its own
            channel.
        color_order: channel order of colour frames: "rgb" (MuJoCo, most libraries) or
            "bgr" (OpenCV's imread).
        compensate_gain: divide each frame by its light level (median ratio to the dark
            reference) before differencing, so that lights that dim or an exposure that
            changes do not produce differences.
        gain_tolerance: a frame whose light level differs from the reference by more than
            this fraction is reported. 0.05: well above the ~0.1% a gain estimate scatters
            by, well below changes that matter.
        on_ratio: every lit frame's level of a candidate must be at least this fraction of
            its brightest lit frame's (less ``level_sigma`` of noise). 0.5: an LED is equally
            bright in all its frames; a light switched by something else is not.
        off_ratio: every code frame where the LED is off must show a level below this
            fraction of the dimmest lit level (plus ``level_sigma`` of noise). 0.25.
        level_sigma: noise allowance on each per-frame level test, in standard deviations of
            that level. 3.
        change_sigma: a pixel changed between the dark frames (someone walked) when their
            range exceeds this many sigma of a difference. 5.
        min_change_area_px: changed regions smaller than this are taken as noise. 3.
        faint_sigma: a missing LED is TOO_FAINT when its code-matched image, smoothed with a
            Gaussian of ``faint_smooth_px``, exceeds this many sigma somewhere (with a
            consistent code). 6: about 1e-4 false alarms per 320 x 240 image (5 would give
            a few percent); smoothing shrinks a single noise pixel by about 0.56, so only a
            spot of several pixels triggers it.
        faint_smooth_px: standard deviation of that Gaussian, px. 1: matched to the
            smallest LEDs (2.5 px).
        noise_floor_dn: smallest noise the detector assumes, DN. 0.5: half a quantisation
            step; noise-free rendered images would otherwise have an infinite SNR.
        saturation_dn: level at which pixels saturate; None: 255 for 8-bit frames; for
            16-bit ones the smallest 2^k - 1 that holds the brightest pixel (a 12-bit
            camera's uint16 frames: 4095; give the camera's own full scale when known);
            no saturation for floats.
        line_tolerance_px: the found LEDs must lie within this distance of a straight image
            line for the line prediction of a missing one (OCCLUDED vs NOT_IN_VIEW). 3:
            allows the bending of a line by lens distortion near the image corners.
        partial_roundness: a found spot of at least ``partial_min_area_px`` and SNR of at
            least ``partial_min_snr`` whose roundness (smaller over larger principal second
            moment) is below this (scaled down by area / ``partial_full_area_px`` for
            smaller spots) is PARTIAL: partly hidden. 0.7: whole LEDs rendered by the twin
            at 6 to 12 m measure at least 0.81 when 30 px or larger and 0.68 at 20-30 px
            (the pixel grid); an LED with a third hidden by a crate measures 0.58 at 34 px
            (its centroid 0.6 px off), two thirds hidden 0.44 at 24 px (1.3 px off), a
            tenth hidden 0.81 (0.2 px off, accepted).
        partial_min_area_px: smallest spot whose roundness is judged, and smallest median
            area of the other LEDs for the area test, px. 20: below that the pixel grid and
            the noise alone make discs look elongated or small.
        partial_full_area_px: spots of this area and more are held to the full
            ``partial_roundness``; smaller ones to a proportionally lower one. 30.
        partial_min_snr: smallest SNR of a spot whose roundness is judged. 30: a dim 12 px
            spot at SNR 20 can measure 0.64 from noise alone.
        partial_area_ratio: a found spot smaller than this fraction of the median area of
            the assembly's other found LEDs is PARTIAL. 0.6: the LEDs of one assembly are
            at about the same distance (their areas differ by less than a quarter at 3 m).
    """

    threshold_sigma: float = 5.0
    min_snr: float = 5.0
    max_area_px: int = 400
    dilate_px: int = 2
    channel: str = "gray"
    color_order: str = "rgb"
    compensate_gain: bool = True
    gain_tolerance: float = 0.05
    on_ratio: float = 0.5
    off_ratio: float = 0.25
    level_sigma: float = 3.0
    change_sigma: float = 5.0
    min_change_area_px: int = 3
    faint_sigma: float = 6.0
    faint_smooth_px: float = 1.0
    noise_floor_dn: float = 0.5
    saturation_dn: float | None = None
    line_tolerance_px: float = 3.0
    partial_roundness: float = 0.7
    partial_min_area_px: int = 20
    partial_full_area_px: int = 30
    partial_min_snr: float = 30.0
    partial_area_ratio: float = 0.6

    def __post_init__(self) -> None:
        positive = (
            "threshold_sigma",
            "min_snr",
            "gain_tolerance",
            "level_sigma",
            "change_sigma",
            "faint_sigma",
            "faint_smooth_px",
            "noise_floor_dn",
            "line_tolerance_px",
            "partial_min_snr",
        )
        for name in positive:
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ValueError(f"DetectorConfig.{name} must be a positive number, got {value!r}")
        for name in ("partial_roundness", "partial_area_ratio"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and 0 <= value <= 1):
                raise ValueError(f"DetectorConfig.{name} must lie in [0, 1], got {value!r}")
        for name in (
            "max_area_px",
            "min_change_area_px",
            "partial_min_area_px",
            "partial_full_area_px",
        ):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise ValueError(f"DetectorConfig.{name} must be a positive integer, got {value!r}")
        if not (isinstance(self.dilate_px, int) and 0 <= self.dilate_px <= 10):
            raise ValueError(
                f"DetectorConfig.dilate_px must be 0..10 pixels, got {self.dilate_px!r}"
            )
        for name in ("on_ratio", "off_ratio"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and 0 < value < 1):
                raise ValueError(f"DetectorConfig.{name} must lie in (0, 1), got {value!r}")
        if self.channel not in CHANNELS:
            raise ValueError(
                f"DetectorConfig.channel must be one of {CHANNELS}, got {self.channel!r}"
            )
        if self.color_order not in COLOR_ORDERS:
            raise ValueError(
                f"DetectorConfig.color_order must be one of {COLOR_ORDERS}, "
                f"got {self.color_order!r}"
            )
        if self.saturation_dn is not None and not (
            math.isfinite(self.saturation_dn) and self.saturation_dn > 0
        ):
            raise ValueError(
                f"DetectorConfig.saturation_dn must be None or positive, got {self.saturation_dn!r}"
            )
