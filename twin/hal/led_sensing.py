"""A :class:`LedSensor` made of a camera and the children's LEDs: the paper's on/off
image subtraction (:func:`calib.detection.detect_leds`). The same for a rendered camera
and a real one."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import numpy as np

from calib.detection import DetectionFailure, DetectorConfig, detect_leds
from calib.detection.sequence import SwitchingSequence
from twin.hal.devices import Camera, Clock, LedSensor, MarkerLeds
from twin.hal.errors import NoFrameError
from twin.hal.readings import CameraImage, LedObservation

SCENE_RETRIES = 2
"""Times a sequence is captured again while an LED comes back ``scene_changed`` (something
moved where it is between the frames: a person walking past, or a frame exposed before the
LEDs switched): the detector's own advice."""

SCENE_CHANGED = DetectionFailure.SCENE_CHANGED.value


class ImageLedSensor(LedSensor):
    """Switch a child's LEDs frame by frame, capture each frame, find the LEDs.

    Args:
        camera: the camera.
        leds: each child's LEDs, by child name.
        clock: the rig's clock (for the time between frames).
        frame_interval: time to wait between frames, s.
        config: the detector's settings.
        led_line: optional (N_led,) LED heights on their mast, m (lets the detector tell an
            occluded LED from one out of view).
        scene_retries: captures of the sequence again while an LED comes back
            ``scene_changed``; the capture that found the most LEDs is kept (the later of
            equals), its ``frames`` counting every image taken.
    """

    def __init__(
        self,
        camera: Camera,
        leds: Mapping[str, MarkerLeds],
        clock: Clock,
        *,
        frame_interval: float = 0.0,
        config: DetectorConfig | None = None,
        led_line: Sequence[float] | None = None,
        scene_retries: int = SCENE_RETRIES,
    ) -> None:
        if not (isinstance(scene_retries, int) and scene_retries >= 0):
            raise ValueError(f"scene_retries must be an integer >= 0, got {scene_retries!r}")
        self._camera = camera
        self._leds = dict(leds)
        self._clock = clock
        self._interval = float(frame_interval)
        self._config = config if config is not None else DetectorConfig()
        self._line = None if led_line is None else np.asarray(led_line, dtype=float)
        self._retries = scene_retries
        self._frames: list[CameraImage] = []  # the last observation's kept capture
        self._taken: list[CameraImage] = []  # the images of the latest capture

    @property
    def camera(self) -> str:
        return self._camera.name

    @property
    def image_size(self) -> tuple[int, int]:
        return self._camera.image_size

    def observe(self, child: str, sequence: SwitchingSequence) -> LedObservation:
        if child not in self._leds:
            raise ValueError(f"no LEDs for child {child!r}; known: {sorted(self._leds)}")
        best = self._capture(child, sequence)
        kept = self._taken
        frames = best.frames
        for _ in range(self._retries):
            if SCENE_CHANGED not in best.failures:
                break
            again = self._capture(child, sequence)
            frames += again.frames
            if again.found.sum() >= best.found.sum():
                best, kept = again, self._taken
        self._frames = kept
        return best if frames == best.frames else dataclasses.replace(best, frames=frames)

    def last_image(self) -> CameraImage | None:
        """The kept capture's frames of the last observation, each pixel at its brightest
        (every LED found shows lit), stamped with the last frame's time; None before the
        first observation or where no frame came."""
        if not self._frames:
            return None
        last = self._frames[-1]
        image = np.maximum.reduce([f.image for f in self._frames])
        return CameraImage(last.camera, last.timestamp, image)

    def _capture(self, child: str, sequence: SwitchingSequence) -> LedObservation:
        """One capture of the sequence and what the detector found in it (its images in
        ``self._taken``)."""
        leds = self._leds[child]
        frames = []
        self._taken = []
        try:
            for k, row in enumerate(sequence.pattern):
                leds.switch([bool(b) for b in row])
                shot = self._camera.capture()
                self._taken.append(shot)
                frames.append(shot.image)
                if self._interval > 0 and k + 1 < len(sequence.pattern):
                    self._clock.sleep(self._interval)
        except NoFrameError:
            # A sequence with a frame missing cannot be decoded: every LED is unseen.
            return self._unseen(child, leds.count, "no_frame", len(frames))
        finally:
            leds.switch([False] * leds.count)
        found = detect_leds(frames, sequence, config=self._config, led_line=self._line)
        pixels = np.full((leds.count, 2), np.nan)
        sigma = np.full(leds.count, np.nan)
        failures: list[str | None] = []
        for d in found.leds:
            if d.pixel is not None:
                pixels[d.led] = d.pixel
                sigma[d.led] = d.sigma_px
                failures.append(None)
            else:
                failures.append(d.failure.value if d.failure is not None else "not_found")
        return LedObservation(
            camera=self.camera,
            child=child,
            timestamp=self._clock.now(),
            pixels=pixels,
            sigma_px=sigma,
            failures=tuple(failures),
            frames=len(frames),
        )

    def _unseen(self, child: str, count: int, failure: str, frames: int) -> LedObservation:
        return LedObservation(
            camera=self.camera,
            child=child,
            timestamp=self._clock.now(),
            pixels=np.full((count, 2), np.nan),
            sigma_px=np.full(count, np.nan),
            failures=(failure,) * count,
            frames=frames,
        )

    def close(self) -> None:
        """The camera and LEDs belong to the rig, which closes them."""
