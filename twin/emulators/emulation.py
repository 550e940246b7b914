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
target", an unreachable goal an ARCOS stall.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from calib.io.camera_files import camera_to_dict
from twin.closing import Closing
from twin.drivers.clock import WallClock
from twin.emulators.links import Link, PtyLink, TcpLink
from twin.outputs import write_text_atomic
from twin.scenario import Scenario, load_scenario
from twin.scenario.limits import check_seed

DEFAULT_TIME_SCALE = 10.0
"""Rig seconds per wall second of ``twin emulate`` (drives take a tenth of their time)."""

LED_BITS = (0, 1, 2, 3, 4, 5, 6, 7)
"""The digital outputs of a child's LEDs, lowest LED first (as many as it has)."""

EMULATOR_STREAM = 7
"""Spawn key of the emulators' own random streams (stopping errors, camera noise)."""

LINKS = ("tcp", "pty")


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
    _closed: bool = field(default=False, repr=False)

    def addresses(self) -> dict[str, str]:
        """What a driver opens for each device: a pty's path, a socket or an HTTP URL."""
        out = {"total_station": self.total_station.address}
        out.update({name: e.address for name, e in self.robots.items()})
        out.update({name: s.url for name, s in self.cameras.items()})
        return out

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
                "timeout_s": 10.0,
            },
            "robots": robots,
            "cameras": [
                {"name": name, "source": server.url, "settle_frames": 1, "timeout_s": 5.0}
                for name, server in self.cameras.items()
            ],
            "emulator": {
                "scenario": str(self.scenario.source or self.scenario.name),
                "truth": truth,
            },
        }

    def write_rig_file(self, path: str | Path) -> Path:
        """Write the rig file at ``path`` and the truth (``truth.json``) beside it."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        truth = path.with_name(path.stem + ".truth.json")
        write_text_atomic(truth, json.dumps({"cameras": self.truth}, indent=2) + "\n")
        write_text_atomic(path, to_toml(self.rig_file(truth.name)))
        return path

    def close(self) -> None:
        """Stop every emulator and close the world's devices; twice is harmless."""
        if self._closed:
            return
        self._closed = True
        for server in self.cameras.values():
            server.close()
        for robot in self.robots.values():
            robot.close()
        self.total_station.close()
        self.sim.close()


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
        time_scale: rig seconds per wall second.
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
    from twin.runner import built_markers
    from twin.sim.rig import FIDELITIES, build_sim_rig
    from twin.sim.world import build_world

    if fidelity not in FIDELITIES:
        raise ValueError(f"fidelity must be one of {FIDELITIES}, got {fidelity!r}")
    if links not in LINKS:
        raise ValueError(f"links must be one of {LINKS}, got {links!r}")
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    if seed is not None:
        sc = sc.model_copy(update={"seed": check_seed(seed)})
    time = WallClock(time_scale)
    world = build_world(sc, markers=built_markers(sc))
    sim = build_sim_rig(world, fidelity)
    lock = threading.RLock()
    streams = np.random.SeedSequence(sc.seed, spawn_key=(EMULATOR_STREAM,)).spawn(
        len(sc.robots.all) + len(sc.cameras)
    )
    rngs = [np.random.default_rng(s) for s in streams]
    started: list[Closing] = []
    try:
        station = GeoComEmulator(sim.rig.total_station, lock).start()
        started.append(station)
        robots: dict[str, Any] = {}
        children = {c.name for c in sc.robots.children}
        leds = len(sc.marker.leds)
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
            emulator = PioneerEmulator(
                body,
                model=_model(robot.model),
                time=time,
                link=link,
                leds=sim.rig.leds.get(robot.name) if robot.name in children else None,
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
                frames = RenderedLedFrames(sim.simulator, cam.name, lock)
            else:
                frames = GeometricLedFrames(world, cam.name, sim.rig.leds, lock, rng)
            server = MjpegServer(frames, fps=camera_fps, **quality).start()
            started.append(server)
            cameras[cam.name] = server
    except BaseException:
        for device in reversed(started):
            device.close()
        sim.close()
        raise
    truth = {
        name: camera_to_dict(sim.frame.camera(world.camera(name))) for name in world.camera_names
    }
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
    )


def to_toml(data: Mapping[str, Any]) -> str:
    """A rig file's mapping as TOML: top-level values, tables, arrays of tables (the
    shapes a rig file has)."""
    lines: list[str] = []
    tables: list[tuple[str, Mapping[str, Any]]] = []
    arrays: list[tuple[str, list[Mapping[str, Any]]]] = []
    for key, value in data.items():
        if isinstance(value, Mapping):
            tables.append((key, value))
        elif isinstance(value, list) and value and all(isinstance(v, Mapping) for v in value):
            arrays.append((key, value))
        else:
            lines.append(f"{key} = {_toml_value(value)}")
    for key, table in tables:
        lines += ["", f"[{key}]", *(f"{k} = {_toml_value(v)}" for k, v in table.items())]
    for key, items in arrays:
        for item in items:
            lines += ["", f"[[{key}]]", *(f"{k} = {_toml_value(v)}" for k, v in item.items())]
    return "\n".join(lines) + "\n"


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"no TOML form for {value!r}")
