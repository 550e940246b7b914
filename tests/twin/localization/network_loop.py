"""A synthetic campaign for the global adjustment's tests: a U-shaped loop of CPS stations
with a known truth, one camera calibrated at the start and again at the end of the loop,
and optionally a control point near the start measured at both ends.

The sequential estimates come from the project's own CPS (:class:`CpsSequence`) and Tsai
calibrations, as a campaign makes them; the network starts from them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from calib import calibrate_tsai
from calib.camera import TsaiCamera
from calib.rotation import rot_z
from calib.tsai import tsai_vector
from twin.localization.network import LedSighting, Network, PointSighting
from twin.localization.observation import ChildObservation
from twin.localization.sequence import CpsSequence

LEDS_Z = np.array([-0.15, 0.05, 0.25, 0.45])
"""The LEDs' heights in W, m (the instrument stands 0.4 m above the floor)."""


@dataclass(frozen=True)
class Noise:
    """Standard deviations: a target's point (m, each axis), a stop's shared LED offset (m),
    each LED's own (m), a pixel (px)."""

    point: float = 1e-3
    stop: float = 1e-3
    led: float = 3e-4
    pixel: float = 0.2


@dataclass(frozen=True)
class Loop:
    """A synthetic campaign: its truth and its network.

    Attributes:
        network: started from the sequential estimates.
        camera: the true camera. stations: (K, 4) true stations.
        sequential: (2, 3) camera centres of the two sequential calibrations, m.
        visits: the stations of the two visits.
    """

    network: Network
    camera: TsaiCamera
    stations: NDArray[np.float64]
    sequential: NDArray[np.float64]
    visits: tuple[int, int]


def _path(step: float = 3.0, length: float = 18.0, width: float = 3.0) -> NDArray[np.float64]:
    """(K, 4) true stations along a U: east along y = 0, north, west along y = width."""
    out = [(0.0, 0.0, 0.0)]
    x = 0.0
    while x < length - 1e-9:
        x += step
        out.append((0.0, x, 0.0))
    out.append((np.pi / 2, length, width))
    while x > 1e-9:
        x -= step
        out.append((np.pi, x, width))
    st = np.array([[yaw, px, py, 0.0] for yaw, px, py in out])
    st[1:, 0] += np.radians(np.linspace(-1.0, 1.0, len(st) - 1))  # the parent never stands square
    st[1:, 3] += 0.003 * np.sin(np.arange(1, len(st)))  # nor level with the start
    return st


def make_loop(
    rng: np.random.Generator,
    noise: Noise = Noise(),
    *,
    control: bool = False,
    cameras: str = "shared",
    stops: int = 14,
) -> Loop:
    """A synthetic campaign drawn with ``rng`` (see the module text)."""
    truth = _path()
    k_last = len(truth) - 1
    camera = TsaiCamera.from_pose(
        f=450.0,
        cx=160.0,
        cy=120.0,
        kappa1=2e-7,
        position=[1.0, 7.5, 2.1],
        view_direction=[0.0, -1.0, -0.5],
    )
    visits = (1, k_last)

    def sight(k: int, world: NDArray, sigma: float) -> tuple[NDArray, NDArray]:
        yaw, t = truth[k, 0], truth[k, 1:]
        level = rot_z(yaw).T @ (world - t) + (rng.normal(0.0, sigma, 3) if sigma else 0.0)
        return level, np.eye(3) * max(sigma, 1e-4) ** 2

    # CPS along the loop: two stands ahead of each station, seen from it and the next.
    cps = CpsSequence(["a", "b"], false_alarm_rate=None)
    targets: list[NDArray] = []
    target_world: list[NDArray] = []
    sightings: list[PointSighting] = []
    estimates = [truth[0].copy()]
    for k in range(k_last):
        nxt = truth[k + 1, 1:]
        heading = np.array([np.cos(truth[k + 1, 0]), np.sin(truth[k + 1, 0]), 0.0])
        side = np.array([-heading[1], heading[0], 0.0])
        stands = [nxt + 1.2 * heading + 1.0 * side, nxt + 0.8 * heading - 1.0 * side]
        obs = []
        for name, world in zip("ab", stands, strict=True):
            level, cov = sight(k, world, noise.point)
            obs.append(ChildObservation(name, level, cov))
            targets.append(world)
            sightings.append(PointSighting(k, len(targets) - 1, level, cov))
        cps.children_moved(obs)
        for name in "ab":
            target_world.append(cps.child_position(name)[0])
        obs = []
        for j, (name, world) in enumerate(zip("ab", stands, strict=True)):
            level, cov = sight(k + 1, world, noise.point)
            obs.append(ChildObservation(name, level, cov))
            sightings.append(PointSighting(k + 1, len(targets) - 2 + j, level, cov))
        cps.parent_moved(obs)
        estimates.append(cps.parent.vector)
    seq_stations = np.array(estimates)
    known = [False] * len(targets)
    control_flags = [False] * len(targets)
    if control:
        point = np.array([-1.5, -1.0, 0.0])
        level0, cov0 = sight(0, point, noise.point)
        level1, cov1 = sight(k_last, point, noise.point)
        target_world.append(point + rng.normal(0.0, noise.point, 3))
        sightings += [
            PointSighting(0, len(target_world) - 1, level0, cov0),
            PointSighting(k_last, len(target_world) - 1, level1, cov1),
        ]
        known.append(False)
        control_flags.append(True)

    # The camera's data at the two visits: a grid of stops in its floor view.
    grid = np.array([(x, y) for x in np.linspace(0.1, 1.9, 4) for y in np.linspace(1.2, 4.2, 4)])[
        :stops
    ]
    leds: list[LedSighting] = []
    starts: list[NDArray] = []
    sequential = []
    for visit, k in enumerate(visits):
        world_all, pix_all = [], []
        yaw_est, t_est = seq_stations[k, 0], seq_stations[k, 1:]
        for x, y in grid:
            world = np.column_stack([np.full(4, x), np.full(4, y), LEDS_Z])
            level = (world - truth[k, 1:]) @ rot_z(truth[k, 0])
            level = level + rng.normal(0.0, noise.stop, 3) + rng.normal(0.0, noise.led, (4, 3))
            cov = noise.stop**2 * np.kron(np.ones((4, 4)), np.eye(3)) + noise.led**2 * np.eye(12)
            pixels = camera.project(world) + rng.normal(0.0, noise.pixel, (4, 2))
            cam_index = 0 if cameras == "shared" else visit
            leds.append(LedSighting(k, cam_index, level, cov, pixels))
            world_all.append(level @ rot_z(yaw_est).T + t_est)
            pix_all.append(pixels)
        result = calibrate_tsai(np.vstack(world_all), np.vstack(pix_all), camera.image_size)
        sequential.append(result.camera.position)
        if cameras == "per_visit" or visit == 0:
            starts.append(tsai_vector(result.camera))
    n_cams = len(starts)
    network = Network(
        stations=seq_stations,
        targets=np.array(target_world),
        known_targets=np.array(known),
        control_targets=np.array(control_flags),
        cameras=np.array(starts),
        image_sizes=np.tile(np.array(camera.image_size), (n_cams, 1)),
        pixel_noise_px=np.full(n_cams, max(noise.pixel, 1e-3)),
        point_sightings=tuple(sightings),
        led_sightings=tuple(leds),
        target_labels=tuple(
            ["stand"] * len(targets) + (["control point start"] if control else [])
        ),
    )
    return Loop(network, camera, truth, np.array(sequential), visits)
