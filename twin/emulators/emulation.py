"""The whole rig emulated: the twin's world behind each device's real protocol.

:func:`start_emulation` builds a scenario's world and its simulated devices (at the
``geometric`` or ``render`` fidelity), then serves them as the hardware would be reached:

- the total station as a Leica GeoCOM instrument on a pseudo-terminal
  (:class:`twin.emulators.geocom.GeoComEmulator` around the simulated instrument);
- each Pioneer speaking ARCOS on a localhost TCP port (as the Pioneer simulators and
  serial-to-Ethernet bridges serve it) or on a pseudo-terminal, moved in the world by the
  velocities the driver sends (:mod:`twin.emulators.arcos`); a child's digital outputs
  switch its LEDs in the world;
- each camera as an MJPEG stream over HTTP on localhost, as IP cameras serve it, showing
  the LEDs as the robots' outputs set them: rendered at the render fidelity, drawn as
  spots at their projected places at the geometric fidelity
  (:mod:`twin.emulators.led_frames`).

It writes a rig file that points at them (:meth:`Emulation.write_rig_file`) and the
world's truth beside it, so that ``twin run SCENARIO --rig RIG.toml`` runs the campaign
over the real protocols and still reports its errors against the truth.

The emulated world may run faster than real time: ``time_scale`` rig seconds pass per wall
second, and the drivers' timeouts and the robots' watchdog follow the rig file's scale.
Scenario faults appear at the protocol level: a lost lock is the instrument's "no
target", an unreachable goal an ARCOS stall, a hidden LED one the cameras show dark for
the LED sequence.
"""

from __future__ import annotations

import contextlib
import json
import math
import threading
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from calib.io.camera_files import camera_to_dict
from twin.closing import Closing
from twin.drivers import rig_file as rig_files
from twin.drivers.clock import WallClock
from twin.emulators.links import Link, PtyLink, TcpLink
from twin.hal.devices import MarkerLeds
from twin.hal.readings import LedSwitch
from twin.hal.wrappers import MarkerLedsWrapper
from twin.outputs import OutputFiles
from twin.scenario import Scenario, load_scenario
from twin.scenario.limits import check_seed

DEFAULT_TIME_SCALE = 10.0
"""Rig seconds per wall second of ``twin emulate`` (drives take a tenth of their time)."""

LED_BITS = (0, 1, 2, 3, 4, 5, 6, 7)
"""The digital outputs of a child's LEDs, lowest LED first (as many as it has)."""

EMULATOR_STREAM = 7
"""Spawn key of the emulators' own random streams (stopping errors, camera noise)."""

LINKS = ("tcp", "pty")

CAMERA_TIMEOUT_WALL = 5.0
"""The cameras' timeout the rig file gives, wall seconds: their streams serve frames in wall
time whatever the time scale (and the first rendered frame takes a fraction of a second),
so their timeout in rig seconds is this many wall seconds at the emulation's scale."""

LINK_TIMEOUT_WALL = 2.5
"""Least wall time the rig file gives the robots' and the instrument's links to answer, s.
Their timeouts are in rig seconds (2 s without a robot's packet, 10 s for an instrument's
reply); at a time scale of 30 those are 67 and 333 ms of wall time, which a busy host (the
emulators and the campaign share its cores, and a render holds the world for tens of
milliseconds) can miss without any device being lost."""

MIN_TIME_SCALE = 1.0
"""Slowest emulated world, rig seconds per wall second: real time, as on real hardware. The
emulators exist to run the drivers and the campaign as fast as the host allows; a slower
world stretches every period of the emulated devices in wall time (a robot's 0.1 s packet,
its 2 s watchdog) past the hardware's, and at the extreme (1e-320) past any finite wait."""

MAX_TIME_SCALE = min(
    rig_files.MAX_TIME_SCALE,
    rig_files.MAX_SECONDS / CAMERA_TIMEOUT_WALL,
    rig_files.MAX_SECONDS / LINK_TIMEOUT_WALL,
)
"""Fastest emulated world: the fastest whose rig file the rig reader accepts (its
``time_scale`` and the timeouts :meth:`Emulation.rig_file` derives from it, at most
:data:`twin.drivers.rig_file.MAX_SECONDS`)."""


def check_time_scale(time_scale: float) -> float:
    """``time_scale`` as a float if it lies in [:data:`MIN_TIME_SCALE`,
    :data:`MAX_TIME_SCALE`].

    Raises:
        ValueError: naming the value and the range.
    """
    value = float(time_scale)
    if not (math.isfinite(value) and MIN_TIME_SCALE <= value <= MAX_TIME_SCALE):
        raise ValueError(
            f"time scale: expected {MIN_TIME_SCALE:g} to {MAX_TIME_SCALE:g} rig seconds per "
            f"wall second, got {time_scale!r}"
        )
    return value


def truth_file(rig_path: str | Path) -> Path:
    """Where :meth:`Emulation.write_rig_file` writes the truth beside the rig file."""
    rig_path = Path(rig_path)
    return rig_path.with_name(rig_path.stem + ".truth.json")


@dataclass
class Emulation(Closing):
    """Emulated devices serving one world. Close it to stop them all.

    Attributes:
        scenario: the scenario played. fidelity: ``geometric`` or ``render``.
        time_scale: rig seconds per wall second.
        total_station: the GeoCOM emulator. robots: each Pioneer emulator by name.
        cameras: each camera's MJPEG server by name.
        truth: each camera's true model in W (:func:`calib.io.camera_files.camera_to_dict`).
        sim: the simulated rig and world the emulators play.
    """

    scenario: Scenario
    fidelity: str
    time_scale: float
    total_station: Any
    robots: dict[str, Any]
    cameras: dict[str, Any]
    truth: dict[str, dict[str, Any]]
    sim: Any
    lock: threading.RLock
    renderer: Closing | None = None
    _closed: bool = field(default=False, repr=False)

    def rig_file(self, truth: str = "truth.json") -> dict[str, Any]:
        """The rig file that points at the emulators, as a mapping."""
        children = {c.name for c in self.scenario.robots.children}
        leds = len(self.scenario.marker.leds)
        robots = []
        for robot in self.scenario.robots.all:
            entry: dict[str, Any] = {
                "name": robot.name,
                "model": _model(robot.model),
                "port": self.robots[robot.name].address,
                "baud": 115200,
                "max_speed_m_s": 0.4,
                "timeout_s": max(2.0, LINK_TIMEOUT_WALL * self.time_scale),
            }
            if robot.name in children:
                entry["led_bits"] = list(LED_BITS[:leds])
            robots.append(entry)
        return {
            "name": f"{self.scenario.name} (emulated)",
            "time_scale": self.time_scale,
            "total_station": {
                "driver": "geocom",
                "port": self.total_station.address,
                "baud": 115200,
                "timeout_s": max(10.0, LINK_TIMEOUT_WALL * self.time_scale),
            },
            "robots": robots,
            "cameras": [
                {
                    "name": name,
                    "source": server.url,
                    # The emulated stream runs fast and a busy machine lets frames queue
                    # in the socket: a frame from before the LEDs switched can arrive
                    # second after the call.
                    "settle_frames": 3,
                    "timeout_s": CAMERA_TIMEOUT_WALL * self.time_scale,
                }
                for name, server in self.cameras.items()
            ],
            "emulator": {
                "scenario": str(self.scenario.source or self.scenario.name),
                "truth": truth,
            },
        }

    def write_rig_file(self, path: str | Path, option: str = "rig file") -> Path:
        """Write the rig file at ``path`` (TOML; YAML for ``.yaml``) and the truth
        (:func:`truth_file`) beside it, both or neither. The rig file is read back with
        the rig reader before it is put in place.

        Raises:
            twin.outputs.OutputError: naming ``option`` and the path: a file that cannot be
                written, or a rig file the reader refuses (nothing is written then).
        """
        path = Path(path)
        truth = truth_file(path)
        text = json.dumps({"cameras": self.truth}, indent=2) + "\n"
        rig = self.rig_file(truth.name)
        with OutputFiles() as files:
            files.stage(truth, option, lambda tmp: tmp.write_text(text, encoding="utf-8"))
            files.stage(path, option, lambda tmp: rig_files.write_rig_file(tmp, rig, path))
        return path

    def close(self) -> None:
        """Stop every emulator and close the world's devices; twice is harmless. Each is
        closed even when another fails to; the first failure is raised at the end."""
        if self._closed:
            return
        self._closed = True
        devices: list[Any] = [
            *self.cameras.values(),
            *self.robots.values(),
            self.total_station,
            self.renderer,
            self.sim,
        ]
        failure: BaseException | None = None
        for device in devices:
            if device is None:
                continue
            try:
                device.close()
            except Exception as exc:
                failure = failure or exc
        if failure is not None:
            raise failure


class HidingLeds(MarkerLedsWrapper):
    """A child's LEDs with the scenario's ``faults.hidden_led_rate``: when the LEDs light
    after being all dark (an LED sequence starts), each stays dark with that probability
    until they are all dark again (the sequence ends), as the twin hides an LED for one
    observation. The camera emulators then show it dark.

    Args:
        inner: the world's LEDs. rate: the probability. rng: the draws.
    """

    def __init__(self, inner: MarkerLeds, rate: float, rng: np.random.Generator) -> None:
        super().__init__(inner)
        self.rate, self.rng = float(rate), rng
        self._hidden = np.zeros(inner.count, dtype=bool)
        self._dark = True

    def switch(self, on: Sequence[bool]) -> LedSwitch:
        flags = np.array([bool(v) for v in on])
        if not flags.any():
            self._dark = True
            self._hidden[:] = False
        elif self._dark and flags.shape == self._hidden.shape:
            self._dark = False
            self._hidden = self.rng.random(len(flags)) < self.rate
        if flags.shape == self._hidden.shape:
            flags &= ~self._hidden
        event = self.inner.switch(flags.tolist())
        return LedSwitch(event.child, event.timestamp, tuple(bool(v) for v in on))


def _model(model: str) -> str:
    """The ARCOS model name of a scenario's robot model."""
    return "p3at" if "3at" in model.lower() else "p3dx"


def start_emulation(
    scenario: Scenario | str | Path,
    *,
    fidelity: str = "geometric",
    seed: int | None = None,
    time_scale: float = DEFAULT_TIME_SCALE,
    links: str = "tcp",
    camera_fps: float = 30.0,
    jpeg_quality: int | None = None,
) -> Emulation:
    """Build ``scenario``'s world and serve its devices over their protocols.

    Args:
        scenario: a scenario or its file.
        fidelity: ``geometric`` (LEDs drawn as spots at their projected places) or
            ``render`` (rendered camera images).
        seed: the root seed (default: the scenario's).
        time_scale: rig seconds per wall second, :data:`MIN_TIME_SCALE` to
            :data:`MAX_TIME_SCALE`.
        links: the robots' links: ``tcp`` (localhost ports) or ``pty`` (pseudo-terminals).
        camera_fps: frames per wall second each camera serves.
        jpeg_quality: the streams' JPEG quality (default: the camera emulator's).

    Raises:
        ValueError: a bad fidelity, links, time scale or seed.
    """
    from twin.emulators.arcos import PioneerEmulator
    from twin.emulators.camera import MjpegServer
    from twin.emulators.geocom import GeoComEmulator
    from twin.emulators.led_frames import GeometricLedFrames, RenderedLedFrames
    from twin.emulators.pioneer_body import PioneerBody
    from twin.emulators.render_thread import RenderThread
    from twin.run.runner import built_markers
    from twin.sim.rig import FIDELITIES, build_sim_rig
    from twin.sim.world import build_world

    if fidelity not in FIDELITIES:
        raise ValueError(f"fidelity must be one of {FIDELITIES}, got {fidelity!r}")
    if links not in LINKS:
        raise ValueError(f"links must be one of {LINKS}, got {links!r}")
    time_scale = check_time_scale(time_scale)
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    if seed is not None:
        sc = sc.model_copy(update={"seed": check_seed(seed)})
    time = WallClock(time_scale)
    world = build_world(sc, markers=built_markers(sc))
    # The devices the emulators wrap (the instrument, the LEDs) are the same at both
    # fidelities: the robots are moved by the velocities the drivers send, and only the
    # cameras' frames differ, rendered in a thread that owns the OpenGL context.
    sim = build_sim_rig(world, "geometric")
    lock = threading.RLock()
    streams = np.random.SeedSequence(sc.seed, spawn_key=(EMULATOR_STREAM,)).spawn(
        len(sc.robots.all) + len(sc.cameras) + 1
    )
    rngs = [np.random.default_rng(s) for s in streams]
    started: list[Closing] = []
    renderer: RenderThread | None = None
    try:
        if fidelity == "render":
            renderer = RenderThread(world, seed=sc.seed)
            started.append(renderer)
        station = GeoComEmulator(sim.rig.total_station, lock).start()
        started.append(station)
        robots: dict[str, Any] = {}
        children = {c.name for c in sc.robots.children}
        leds = len(sc.marker.leds)
        world_leds: dict[str, MarkerLeds] = dict(sim.rig.leds)
        if sc.faults.hidden_led_rate > 0:
            world_leds = {
                n: HidingLeds(d, sc.faults.hidden_led_rate, rngs[-1]) for n, d in world_leds.items()
            }
        for k, robot in enumerate(sc.robots.all):
            body = PioneerBody(
                world,
                robot.name,
                sim.frame,
                lock,
                stopping=sc.noise.stopping,
                rng=rngs[k],
                unreachable=sc.faults.unreachable,
            )
            link: Link = TcpLink() if links == "tcp" else PtyLink()
            started.append(link)
            emulator = PioneerEmulator(
                body,
                model=_model(robot.model),
                time=time,
                link=link,
                leds=world_leds.get(robot.name) if robot.name in children else None,
                led_bits=LED_BITS[:leds] if robot.name in children else (),
                robot_name=robot.name,
            ).start()
            started.append(emulator)
            robots[robot.name] = emulator
        cameras: dict[str, Any] = {}
        quality = {} if jpeg_quality is None else {"quality": jpeg_quality}
        for k, cam in enumerate(sc.cameras):
            rng = rngs[len(sc.robots.all) + k]
            if fidelity == "render":
                assert renderer is not None
                frames = RenderedLedFrames(renderer, cam.name, lock)
            else:
                frames = GeometricLedFrames(world, cam.name, sim.rig.leds, lock, rng)
            server = MjpegServer(frames, fps=camera_fps, **quality).start()
            started.append(server)
            cameras[cam.name] = server
        truth = {
            name: camera_to_dict(sim.frame.camera(world.camera(name)))
            for name in world.camera_names
        }
    except BaseException:
        for device in reversed(started):
            with contextlib.suppress(Exception):
                device.close()
        sim.close()
        raise
    return Emulation(
        scenario=sc,
        fidelity=fidelity,
        time_scale=float(time_scale),
        total_station=station,
        robots=robots,
        cameras=cameras,
        truth=truth,
        sim=sim,
        lock=lock,
        renderer=renderer,
    )
