"""The children's LEDs and the cameras' view of them, at both fidelities."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from calib.camera import TsaiCamera
from calib.detection import DetectionFailure
from calib.detection.sequence import SwitchingSequence
from calib.opencv_camera import OpenCVCamera
from twin.hal.devices import Camera, Clock, LedSensor, MarkerLeds
from twin.hal.led_sensing import ImageLedSensor
from twin.hal.readings import CameraImage, LedObservation, LedSwitch
from twin.sim.capture import (
    FRAME_INTERVAL,
    CameraSimulator,
    in_image,
    led_radii,
    led_visible_fraction,
    project_or_nan,
)
from twin.sim.robots import N_LEDS
from twin.sim.world import World
from twin.timing import timed


class SimLeds(MarkerLeds):
    """A child's LEDs: switching changes their material in the world.

    ``hidden`` LEDs stay dark whatever they are switched to (an injected fault).
    """

    def __init__(self, world: World, child: str, clock: Clock) -> None:
        self.world = world
        self._child = child
        self.clock = clock
        self.hidden: frozenset[int] = frozenset()

    @property
    def child(self) -> str:
        return self._child

    @property
    def count(self) -> int:
        return N_LEDS

    def switch(self, on: Sequence[bool]) -> LedSwitch:
        flags = tuple(bool(f) for f in on)
        if len(flags) != N_LEDS:
            raise ValueError(f"give {N_LEDS} flags, got {len(flags)}")
        self.world.sensing.set_leds(
            self._child, [f and k not in self.hidden for k, f in enumerate(flags)]
        )
        return LedSwitch(self._child, self.clock.now(), flags)

    def close(self) -> None:
        self.world.sensing.set_leds(self._child, False)


class SimCamera(Camera):
    """A rendered camera (lens, sensor noise) of the world."""

    def __init__(
        self, simulator: CameraSimulator, name: str, clock: Clock, timings: dict[str, float]
    ) -> None:
        self.simulator = simulator
        self._name = name
        self.clock = clock
        self.timings = timings

    @property
    def name(self) -> str:
        return self._name

    @property
    def image_size(self) -> tuple[int, int]:
        w, h = self.simulator.world.scenario.camera(self._name).image_size
        return (w, h)

    def capture(self) -> CameraImage:
        with timed(self.timings, "render"):
            frame = self.simulator.capture(self._name)
        return CameraImage(self._name, self.clock.now(), frame.image)

    def close(self) -> None:
        """The simulator belongs to the rig's builder, which closes it."""


def _focal(camera: TsaiCamera | OpenCVCamera) -> float:
    return camera.f if isinstance(camera, TsaiCamera) else camera.fx


def _draw_hidden(rate: float, rng: np.random.Generator) -> frozenset[int]:
    if rate <= 0:
        return frozenset()
    return frozenset(int(k) for k in np.flatnonzero(rng.random(N_LEDS) < rate))


@dataclasses.dataclass(frozen=True, eq=False)
class LedView:
    """How a camera sees a child's LEDs now, by the geometric fidelity's rules.

    Attributes:
        pixels: (N_LEDS, 2) true pixel of each LED's centre (the camera model's projection,
            distortion included), NaN behind the camera.
        radius_px: (N_LEDS,) each LED's radius in the image, px (focal length x radius /
            distance).
        failures: per LED, None when it is wholly inside the image and wholly visible, else
            the :class:`calib.detection.DetectionFailure` value: ``not_in_view``,
            ``occluded`` (wholly hidden, or an injected hidden LED) or ``partial``.
    """

    pixels: NDArray[np.float64]
    radius_px: NDArray[np.float64]
    failures: tuple[str | None, ...]

    @property
    def found(self) -> NDArray[np.bool_]:
        """(N_LEDS,) which LEDs are wholly seen."""
        return np.array([f is None for f in self.failures])


def view_leds(
    world: World,
    camera: TsaiCamera | OpenCVCamera,
    child: str,
    radii: Mapping[tuple[str, int], float],
    hidden: frozenset[int] = frozenset(),
) -> LedView:
    """Project a child's LEDs through ``camera`` and decide which the camera sees wholly.

    An LED is seen when it is inside the image by more than its own image radius and
    wholly visible from the camera (MuJoCo ray casts to its centre and outline,
    :func:`twin.sim.capture.led_visible_fraction`); partly hidden it is ``partial``, wholly
    hidden ``occluded``, outside ``not_in_view``. LEDs in ``hidden`` (inside the image)
    are ``occluded`` without a ray cast.

    Args:
        world: the world, in its current state. camera: the true camera model.
        child: the child's name. radii: every LED's radius, m (:func:`led_radii`).
        hidden: indices of LEDs hidden by an injected fault.
    """
    _, leds = world.marker_points(child)
    pixels = project_or_nan(camera, leds)
    origin = camera.position
    radius_px = np.full(N_LEDS, np.nan)
    failures: list[str | None] = []
    for k in range(N_LEDS):
        radius = radii[(child, k)]
        distance = float(np.linalg.norm(leds[k] - origin))
        margin = _focal(camera) * radius / distance
        radius_px[k] = margin
        if not in_image(pixels[k : k + 1], camera.image_size, margin)[0]:
            failures.append(DetectionFailure.NOT_IN_VIEW.value)
            continue
        if k in hidden:
            failures.append(DetectionFailure.OCCLUDED.value)
            continue
        seen = led_visible_fraction(world, origin, leds[k], radius)
        if seen < 1.0:
            failures.append(
                DetectionFailure.OCCLUDED.value if seen == 0 else DetectionFailure.PARTIAL.value
            )
            continue
        failures.append(None)
    return LedView(pixels=pixels, radius_px=radius_px, failures=tuple(failures))


class RenderLedSensor(ImageLedSensor):
    """:class:`ImageLedSensor` on a rendered camera, with injected hidden LEDs and the real
    camera's centroid error (``centroid_px`` per coordinate, from ``centroid_rng``) added to
    what the detector found."""

    def __init__(
        self,
        camera: SimCamera,
        leds: dict[str, SimLeds],
        clock: Clock,
        timings: dict[str, float],
        led_line: Sequence[float],
        hidden_led_rate: float = 0.0,
        fault_rng: np.random.Generator | None = None,
        centroid_px: float = 0.0,
        centroid_rng: np.random.Generator | None = None,
    ) -> None:
        super().__init__(camera, leds, clock, frame_interval=FRAME_INTERVAL, led_line=led_line)
        self.centroid_px = float(centroid_px)
        self.centroid_rng = centroid_rng if centroid_rng is not None else np.random.default_rng(0)
        self.sim_leds = leds
        self.timings = timings
        self.hidden_led_rate = hidden_led_rate
        self.fault_rng = fault_rng if fault_rng is not None else np.random.default_rng(0)

    def observe(self, child: str, sequence: SwitchingSequence) -> LedObservation:
        leds = self.sim_leds[child]
        leds.hidden = _draw_hidden(self.hidden_led_rate, self.fault_rng)
        try:
            with timed(self.timings, "observe"):
                seen = super().observe(child, sequence)
        finally:
            leds.hidden = frozenset()
        if self.centroid_px == 0.0:
            return seen
        error = self.centroid_px * self.centroid_rng.standard_normal(seen.pixels.shape)
        return dataclasses.replace(
            seen,
            pixels=seen.pixels + error,
            sigma_px=np.hypot(seen.sigma_px, self.centroid_px),
        )


class GeometricLedSensor(LedSensor):
    """LEDs projected through the true camera, with the detection noise of the render
    fidelity (geometric fidelity).

    An LED is found when it is inside the image by more than its own image radius and
    wholly visible from the camera (MuJoCo ray casts to its centre and outline); partly
    hidden it is ``partial``, wholly hidden ``occluded``, outside ``not_in_view``: the
    render fidelity's detector reports the same cases.

    Args:
        world: the world. camera: the camera's name.
        clock: the rig's clock (advanced by the sequence's duration).
        sigma_px: detection noise, px per coordinate. rng: its random generator.
        hidden_led_rate: probability that an LED is hidden (injected fault).
        fault_rng: random generator of the faults.
    """

    def __init__(
        self,
        world: World,
        camera: str,
        clock: Clock,
        sigma_px: float,
        rng: np.random.Generator,
        hidden_led_rate: float = 0.0,
        fault_rng: np.random.Generator | None = None,
    ) -> None:
        self.world = world
        self._camera = camera
        self.clock = clock
        self.sigma_px = float(sigma_px)
        self.rng = rng
        self.hidden_led_rate = hidden_led_rate
        self.fault_rng = fault_rng if fault_rng is not None else np.random.default_rng(0)
        self._radius = led_radii(world)
        self._model = world.camera(camera)

    @property
    def camera(self) -> str:
        return self._camera

    @property
    def image_size(self) -> tuple[int, int]:
        w, h = self._model.image_size
        return (w, h)

    def observe(self, child: str, sequence: SwitchingSequence) -> LedObservation:
        if child not in {c.name for c in self.world.scenario.robots.children}:
            raise ValueError(f"no child {child!r}")
        hidden = _draw_hidden(self.hidden_led_rate, self.fault_rng)
        view = view_leds(self.world, self._model, child, self._radius, hidden)
        out = np.full((N_LEDS, 2), np.nan)
        sigma = np.full(N_LEDS, np.nan)
        for k in np.flatnonzero(view.found):
            out[k] = view.pixels[k] + self.sigma_px * self.rng.standard_normal(2)
            sigma[k] = self.sigma_px
        failures = view.failures
        if hasattr(self.clock, "pass_time"):
            self.clock.pass_time(len(sequence.pattern) * FRAME_INTERVAL)
        return LedObservation(
            camera=self._camera,
            child=child,
            timestamp=self.clock.now(),
            pixels=out,
            sigma_px=sigma,
            failures=tuple(failures),
            frames=0,
        )

    def close(self) -> None:
        """Nothing to release."""
