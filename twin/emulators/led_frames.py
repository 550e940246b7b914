"""The images of the twin's cameras, for an emulated camera to serve
(:class:`twin.emulators.camera.MjpegServer`).

Two fidelities, as the simulated rig has:

- :class:`GeometricLedFrames`: a plain background with sensor noise and a Gaussian spot for
  every LED that is lit and wholly seen, at its true projected pixel. Which LEDs are seen is
  decided exactly as :class:`twin.sim.rig.leds.GeometricLedSensor` decides it
  (:func:`twin.sim.rig.leds.view_leds`: inside the image by its own radius, MuJoCo ray casts
  to its centre and outline), so the detector run on these images finds what the
  geometric sensor reports.
- :class:`RenderedLedFrames`: the rendered image of the camera
  (:class:`twin.sim.capture.CameraSimulator`: lens, sensor noise).

Both are called from the server's threads while other threads move the robots: they hold
the world's lock while they read it.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray
from scipy.special import ndtr

from twin.sim.capture import CameraSimulator, led_radii
from twin.sim.rig.leds import SimLeds, view_leds
from twin.sim.world import World

PSF_SIGMA_PX = 0.5
"""Standard deviation of the lens and pixel blur added to an LED's own size, px. An LED's
disc of image radius r has a second moment of r / 2 per axis; the spot drawn has the
standard deviation hypot(r / 2, PSF_SIGMA_PX), so that even a distant LED covers a few
pixels and its centroid is not tied to the pixel grid."""

SPOT_EXTENT_SIGMA = 5.0
"""A spot is drawn out to this many standard deviations from its centre."""


def gaussian_spot(
    image: NDArray[np.float64], centre: NDArray[np.float64], sigma: float, peak: float
) -> None:
    """Add a pixel-integrated Gaussian spot to ``image`` in place.

    Each pixel gets the spot's integral over its own square, so the spot's intensity-weighted
    centroid is ``centre`` to far below 0.01 px for ``sigma`` >= 0.5 px.

    Args:
        image: (H, W) float image, DN.
        centre: (2,) (u, v) in OpenCV pixels ((0, 0) the centre of the top-left pixel).
        sigma: standard deviation of the spot, px.
        peak: the spot's peak level, DN (the level at its centre before pixel integration).
    """
    h, w = image.shape
    u, v = (float(c) for c in centre)
    reach = SPOT_EXTENT_SIGMA * sigma
    u0, u1 = max(int(np.floor(u - reach)), 0), min(int(np.ceil(u + reach)) + 1, w)
    v0, v1 = max(int(np.floor(v - reach)), 0), min(int(np.ceil(v + reach)) + 1, h)
    if u0 >= u1 or v0 >= v1:
        return
    cols = np.arange(u0, u1, dtype=float)
    rows = np.arange(v0, v1, dtype=float)
    gx = ndtr((cols + 0.5 - u) / sigma) - ndtr((cols - 0.5 - u) / sigma)
    gy = ndtr((rows + 0.5 - v) / sigma) - ndtr((rows - 0.5 - v) / sigma)
    # The integral of a unit-peak Gaussian over the plane is 2 pi sigma^2.
    image[v0:v1, u0:u1] += (peak * 2.0 * np.pi * sigma**2) * np.outer(gy, gx)


class GeometricLedFrames:
    """A camera's frames at the geometric fidelity: lit, seen LEDs as Gaussian spots.

    Calling it returns one (H, W) uint8 frame of the world as it is now.

    Args:
        world: the world (robots placed in it, LEDs switched by :class:`SimLeds`).
        camera: the camera's name.
        leds: each child's LEDs, by child name (their switched state is in the world).
        lock: held while the world is read (other threads move the robots).
        rng: random generator of the sensor noise.
        background: level of the plain background, DN.
        noise_dn: standard deviation of the sensor noise per pixel, DN.
        peak_dn: peak level of an LED's spot above the background, DN.
    """

    def __init__(
        self,
        world: World,
        camera: str,
        leds: Mapping[str, SimLeds],
        lock: threading.RLock,
        rng: np.random.Generator,
        *,
        background: float = 20.0,
        noise_dn: float = 2.0,
        peak_dn: float = 200.0,
    ) -> None:
        for name, value in (("background", background), ("peak_dn", peak_dn)):
            if not (np.isfinite(value) and 0 <= value <= 255):
                raise ValueError(f"{name} must be a level in 0..255 DN, got {value!r}")
        if not (np.isfinite(noise_dn) and noise_dn >= 0):
            raise ValueError(f"noise_dn must be >= 0 DN, got {noise_dn!r}")
        self.world = world
        self.camera = camera
        self.leds = dict(leds)
        self.lock = lock
        self.rng = rng
        self.background = float(background)
        self.noise_dn = float(noise_dn)
        self.peak_dn = float(peak_dn)
        self._noise_lock = threading.Lock()
        with lock:
            self._model = world.camera(camera)
            self._radius = led_radii(world)
        w, h = self._model.image_size
        self.image_size = (int(w), int(h))

    def spots(self) -> list[tuple[str, int, NDArray[np.float64], float]]:
        """(child, LED, (2,) pixel, spot sigma px) of every LED drawn now."""
        out = []
        with self.lock:
            for child in self.leds:
                lit = self.world.sensing.leds_on(child)
                view = view_leds(self.world, self._model, child, self._radius)
                for k in np.flatnonzero(view.found):
                    if lit[k]:
                        sigma = float(np.hypot(0.5 * view.radius_px[k], PSF_SIGMA_PX))
                        out.append((child, int(k), view.pixels[k].copy(), sigma))
        return out

    def __call__(self) -> NDArray[np.uint8]:
        w, h = self.image_size
        image = np.full((h, w), self.background)
        for _, _, pixel, sigma in self.spots():
            gaussian_spot(image, pixel, sigma, self.peak_dn)
        if self.noise_dn > 0:
            with self._noise_lock:  # a Generator is not for several threads at once
                image += self.noise_dn * self.rng.standard_normal(image.shape)
        return np.clip(np.rint(image), 0, 255).astype(np.uint8)


class RenderedLedFrames:
    """A camera's frames at the render fidelity: the simulator's image of the camera.

    Calling it returns the rendered (H, W, 3) uint8 RGB frame of the world as it is now; a
    sensor of more than 8 bits is cut to its top 8 (what an MJPEG camera sends).

    Args:
        simulator: the world's camera simulator (not for several threads: the lock
            serialises the renders).
        camera: the camera's name.
        lock: held while the world is rendered.
    """

    def __init__(self, simulator: CameraSimulator, camera: str, lock: threading.RLock) -> None:
        if camera not in simulator.world.camera_names:
            raise ValueError(
                f"no camera {camera!r}; the world's cameras are {simulator.world.camera_names}"
            )
        self.simulator = simulator
        self.camera = camera
        self.lock = lock
        self._shift = simulator.world.scenario.camera(camera).sensor.bits - 8

    def __call__(self) -> NDArray[np.uint8]:
        with self.lock:
            image = self.simulator.capture(self.camera).image
        if self._shift > 0:
            return (image >> self._shift).astype(np.uint8)
        return np.asarray(image, dtype=np.uint8)
