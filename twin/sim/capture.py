"""Camera frames as the twin's cameras would deliver them, each with its ground truth.

A frame is rendered as a pinhole image (:mod:`twin.sim.render`), distorted and
pixel-integrated by the camera's lens (:mod:`twin.sim.lens`), and exposed on its sensor
(:mod:`twin.sim.sensor`). Its ground truth, kept apart from the image, gives for every LED
of every child its world position, its true pixel (the camera model's own projection,
distortion included), whether it is lit, inside the image and how much of it the camera
sees.

:meth:`CameraSimulator.capture_sequence` takes the frames of an LED switching sequence
(the paper finds each LED by subtracting an LED-off image from an LED-on image): it
switches the child's LEDs frame by frame, applies the scenario's light flicker and drift,
and lets the world run between frames, so people walk on during the capture.
"""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from dataclasses import dataclass, field

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.camera import TsaiCamera
from calib.opencv_camera import OpenCVCamera
from twin.closing import Closing
from twin.scenario.schema import SensorConfig
from twin.sim.lens import LensWarp, lens_warp
from twin.sim.render import CameraRenderer
from twin.sim.robots import N_LEDS
from twin.sim.sensor import expose
from twin.sim.world import World

# Stream of numpy.random.SeedSequence reserved for sensor noise and light flicker.
SENSOR_STREAM = 2

# Time between the frames of a switching sequence, s (a 15 frame/s camera).
FRAME_INTERVAL = 1.0 / 15.0

# Points on an LED's outline, as a fraction of its radius, whose lines of sight give the
# visible fraction (with the centre); and the number of them.
OUTLINE_FRACTION = 0.8
OUTLINE_POINTS = 8


@dataclass(frozen=True)
class LedTruth:
    """The truth about one LED in one frame.

    Attributes:
        child: the child robot carrying it. led: its index (0 lowest by default).
        position: (3,) centre in the world frame, m.
        pixel: (2,) true pixel of the centre (the camera model's projection, distortion
            included), NaN when the LED is behind the camera.
        in_image: whether the centre projects inside the image.
        visible_fraction: share of the LED (its centre and points around its outline, as
            the camera looks at it) with a clear line of sight from the camera, 0..1.
        lit: whether it was switched on.
        distance: from the camera's optical centre, m.
    """

    child: str
    led: int
    position: NDArray[np.float64] = field(repr=False)
    pixel: NDArray[np.float64]
    in_image: bool
    visible_fraction: float
    lit: bool
    distance: float

    @property
    def visible(self) -> bool:
        """Inside the image and not hidden at all."""
        return self.in_image and self.visible_fraction >= 1.0


@dataclass(frozen=True)
class Frame:
    """One camera image and its ground truth.

    Attributes:
        camera: the camera's name.
        time: simulation time of the exposure, s.
        image: (H, W, 3) RGB, uint8 (or uint16 for a sensor of more than 8 bits).
        light_level: level of the lights relative to the scenario's.
        leds: the truth for every LED of every child, in child then LED order.
        people: (name, (2,) floor position in m) of every person, where the image shows
            them.
    """

    camera: str
    time: float
    image: NDArray[np.uint8] | NDArray[np.uint16] = field(repr=False)
    light_level: float
    leds: tuple[LedTruth, ...] = field(repr=False)
    people: tuple[tuple[str, NDArray[np.float64]], ...] = field(repr=False, default=())

    def truth(self, child: str) -> tuple[LedTruth, ...]:
        """The truth for one child's LEDs, in LED order."""
        out = tuple(t for t in self.leds if t.child == child)
        if not out:
            raise KeyError(f"no child {child!r} in the frame's truth")
        return out

    def pixels(self, child: str) -> NDArray[np.float64]:
        """(N_LEDS, 2) true pixels of a child's LEDs."""
        return np.array([t.pixel for t in self.truth(child)])


class CameraSimulator(Closing):
    """Renders a world's cameras through their lens and sensor, with ground truth.

    Args:
        world: the world (its current state is captured).
        seed: seed of the sensor noise and flicker (default: from the scenario's seed).

    Use as a context manager or call :meth:`close` (it holds rendering contexts). Not for
    use from several threads: each render sets the camera's intrinsics in the shared
    model for its duration.
    """

    def __init__(self, world: World, seed: int | None = None) -> None:
        self.world = world
        root = world.scenario.seed if seed is None else seed
        # Independent streams: the light's flicker, and each camera's sensor noise, so that
        # switching the noise off or capturing another camera first changes nothing else.
        streams = np.random.SeedSequence(root, spawn_key=(SENSOR_STREAM,)).spawn(
            1 + len(world.camera_names)
        )
        self.flicker_rng = np.random.default_rng(streams[0])
        self.noise_rng = {
            name: np.random.default_rng(seq)
            for name, seq in zip(world.camera_names, streams[1:], strict=True)
        }
        self.renderer = CameraRenderer(world)
        self._warps: dict[tuple[str, int], LensWarp] = {}
        self._led_radius = led_radii(world)

    def warp(self, camera: str, supersample: int | None = None) -> LensWarp:
        """The lens remap of a camera (cached), at the sensor's or the given supersampling."""
        s = (
            self.world.scenario.camera(camera).sensor.supersample
            if supersample is None
            else supersample
        )
        key = (camera, int(s))
        if key not in self._warps:
            self._warps[key] = lens_warp(self.world.camera(camera), int(s))
        return self._warps[key]

    def capture(self, camera: str, sensor: SensorConfig | None = None) -> Frame:
        """One frame of ``camera`` now.

        Args:
            camera: the camera's name.
            sensor: sensor settings to use instead of the scenario's (e.g. noise off).
        """
        cfg = self.world.scenario.camera(camera)
        sensor = cfg.sensor if sensor is None else sensor
        warp = self.warp(camera, sensor.supersample)
        levels = warp.apply(self.renderer.render_view(camera, warp.view))
        image = expose(levels, sensor, self.noise_rng[camera] if sensor.noise else None)
        return Frame(
            camera=camera,
            time=self.world.time,
            image=image,
            light_level=self.world.sensing.light_level,
            leds=self.led_truth(camera),
            people=tuple(
                (p.name, self.world.data.xpos[self.world.model.body(p.name).id][:2].copy())
                for p in self.world.scenario.people
            ),
        )

    def capture_sequence(
        self,
        camera: str,
        child: str,
        pattern: ArrayLike,
        frame_interval: float = FRAME_INTERVAL,
        sensor: SensorConfig | None = None,
    ) -> list[Frame]:
        """The frames of an LED switching sequence.

        For each row of ``pattern`` the child's LEDs are switched as it says, the light
        level is set (the scenario's ``flicker`` and ``drift_per_frame`` around the level
        at the start), the frame is captured, and the world runs ``frame_interval``
        seconds. Afterwards the LEDs are off and the light level is back where it was.

        Args:
            camera: the camera's name. child: the child whose LEDs are switched.
            pattern: (n_frames, 4) bool, which LEDs are lit in each frame; or an object
                with such a ``pattern`` attribute (:class:`calib.detection.SwitchingSequence`).
            frame_interval: time between frames, s (0: the world stands still); the world
                runs whole control periods, so it is rounded to one (0.02 s by default).
            sensor: sensor settings to use instead of the scenario's.
        """
        rows = np.asarray(getattr(pattern, "pattern", pattern), dtype=bool)
        if rows.ndim != 2 or rows.shape[1] != N_LEDS or rows.shape[0] < 1:
            raise ValueError(f"pattern must have shape (n_frames, {N_LEDS}), got {rows.shape}")
        if frame_interval < 0:
            raise ValueError(f"frame_interval must be >= 0 s, got {frame_interval}")
        lighting = self.world.scenario.space.lighting
        start_level = self.world.sensing.light_level
        frames = []
        try:
            for k, row in enumerate(rows):
                self.world.sensing.set_leds(child, [bool(b) for b in row])
                level = start_level * (1.0 + lighting.drift_per_frame) ** k
                if lighting.flicker > 0:
                    level *= max(0.0, 1.0 + lighting.flicker * self.flicker_rng.standard_normal())
                self.world.sensing.set_light_level(level)
                frames.append(self.capture(camera, sensor))
                if frame_interval > 0 and k + 1 < len(rows):
                    self.world.run(frame_interval)
        finally:
            self.world.sensing.set_leds(child, False)
            self.world.sensing.set_light_level(start_level)
        return frames

    def led_truth(self, camera: str) -> tuple[LedTruth, ...]:
        """The truth for every LED of every child, seen from ``camera`` now."""
        cam = self.world.camera(camera)
        origin = cam.position
        out = []
        for child in self.world.scenario.robots.children:
            _, leds = self.world.marker_points(child.name)
            lit = self.world.sensing.leds_on(child.name)
            pixels = project_or_nan(cam, leds)
            inside = in_image(pixels, cam.image_size)
            for k, p in enumerate(leds):
                radius = self._led_radius[(child.name, k)]
                out.append(
                    LedTruth(
                        child=child.name,
                        led=k,
                        position=p,
                        pixel=pixels[k],
                        in_image=bool(inside[k]),
                        visible_fraction=led_visible_fraction(self.world, origin, p, radius),
                        lit=lit[k],
                        distance=float(np.linalg.norm(p - origin)),
                    )
                )
        return tuple(out)

    def close(self) -> None:
        """Free the rendering contexts."""
        self.renderer.close()


def led_radii(world: World) -> dict[tuple[str, int], float]:
    """Radius of every LED's geom, m, by (child, LED index)."""
    out = {}
    for child in world.scenario.robots.children:
        for k in range(N_LEDS):
            g = mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_GEOM, f"{child.name}/led{k}")
            out[(child.name, k)] = float(world.model.geom_size[g][0])
    return out


def led_visible_fraction(
    world: World, origin: NDArray[np.float64], centre: NDArray[np.float64], radius: float
) -> float:
    """Share of an LED seen from ``origin``: its centre and ``OUTLINE_POINTS`` points on a
    ring of ``OUTLINE_FRACTION`` times its ``radius`` (m), each by a MuJoCo ray cast."""
    view = centre - origin
    view = view / np.linalg.norm(view)
    a = np.cross(view, [0.0, 0.0, 1.0])
    if np.linalg.norm(a) < 1e-9:
        a = np.cross(view, [1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(view, a)
    angles = 2.0 * np.pi * np.arange(OUTLINE_POINTS) / OUTLINE_POINTS
    ring = OUTLINE_FRACTION * radius * (np.outer(np.cos(angles), a) + np.outer(np.sin(angles), b))
    points = np.vstack([centre, centre + ring])
    # Anything within the LED's own radius of the target point is the LED itself.
    seen = [world.sensing.line_of_sight(origin, q, tolerance=1.25 * radius) for q in points]
    return float(np.mean(seen))


def project_or_nan(camera: TsaiCamera | OpenCVCamera, points: ArrayLike) -> NDArray[np.float64]:
    """(N, 3) world points -> (N, 2) pixels, NaN for points behind the camera or beyond
    the lens model's fold."""
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    z = (p @ camera.world2cam_r.T + camera.world2cam_t)[:, 2]
    out = np.full((len(p), 2), np.nan)
    for i in np.flatnonzero(z > 0):
        with contextlib.suppress(ValueError):
            out[i] = camera.project(p[i : i + 1])[0]
    return out


def in_image(
    pixels: ArrayLike, image_size: Sequence[int], margin: ArrayLike = 0.0
) -> NDArray[np.bool_]:
    """(N,) whether (N, 2) pixels lie inside an image of ``image_size`` (width, height), at
    least ``margin`` (scalar or (N,), px) from its edge (a blob's radius: all of it inside)."""
    uv = np.asarray(pixels, dtype=float).reshape(-1, 2)
    m = np.asarray(margin, dtype=float).reshape(-1)
    w, h = image_size
    with np.errstate(invalid="ignore"):
        return (
            np.isfinite(uv).all(axis=1)
            & (uv[:, 0] >= m - 0.5)
            & (uv[:, 0] <= w - 0.5 - m)
            & (uv[:, 1] >= m - 0.5)
            & (uv[:, 1] <= h - 0.5 - m)
        )
