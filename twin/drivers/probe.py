"""What ``twin devices`` does: open every device of a rig file, ask what it is, blink each
child's LEDs in front of every camera, and close them all.

The first thing to run on real hardware: it needs no scenario and moves no robot.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from calib.detection.sequence import SwitchingSequence
from twin.closing import Closing
from twin.drivers.build import (
    close_all,
    identify,
    open_camera,
    open_connection,
    open_leds,
    open_total_station,
)
from twin.drivers.clock import WallClock
from twin.drivers.rig_file import RigFile
from twin.hal.led_sensing import ImageLedSensor
from twin.scenario.schema import Noise


@dataclass
class DeviceReport:
    """What one device said, or why it could not be opened.

    Attributes:
        device: ``total_station``, a robot's or a camera's name.
        kind: ``total station``, ``robot``, ``camera``, ``LEDs``.
        where: its port, URL or source.
        ok: whether it answered.
        facts: what it reported (names, serial number, battery, resolution, frame rate,
            LEDs seen), or ``{"error": ...}``.
    """

    device: str
    kind: str
    where: str
    ok: bool
    facts: dict[str, Any] = field(default_factory=dict)


def probe_rig(
    rig: RigFile, report: Callable[[DeviceReport], None] | None = None, blink: bool = True
) -> list[DeviceReport]:
    """Open each device of ``rig`` in turn and report what it is.

    Args:
        rig: the rig file.
        report: called with each :class:`DeviceReport` as it is made.
        blink: switch each child's LEDs in front of every camera and count the LEDs found.

    Returns:
        Every report: one per device, then one per child and camera blinked.
    """
    clock = WallClock(rig.time_scale)
    out: list[DeviceReport] = []
    opened: list[Closing] = []

    def note(r: DeviceReport) -> None:
        out.append(r)
        if report is not None:
            report(r)

    def attempt(device: str, kind: str, where: str, make: Callable[[], Any]) -> Any:
        handle = None
        try:
            handle = make()
            facts = identify(handle)
        except Exception as exc:
            if handle is not None:
                close_all([handle])
            note(
                DeviceReport(device, kind, where, False, {"error": f"{type(exc).__name__}: {exc}"})
            )
            return None
        opened.append(handle)
        note(DeviceReport(device, kind, where, True, facts))
        return handle

    try:
        ts = rig.total_station
        attempt(
            "total_station",
            "total station",
            ts.port,
            lambda: open_total_station(ts, clock, Noise()),
        )
        leds = {}
        for robot in rig.robots:
            connection = attempt(
                robot.name, "robot", robot.port, lambda r=robot: open_connection(r, clock)
            )
            if connection is not None and robot.led_bits:
                leds[robot.name] = open_leds(connection, robot)
        cameras = {}
        for cam in rig.cameras:
            camera = attempt(
                cam.name, "camera", str(cam.source), lambda c=cam: open_camera(c, clock)
            )
            if camera is not None:
                cameras[cam.name] = camera
        if blink:
            for name, camera in cameras.items():
                sensor = ImageLedSensor(camera, leds, clock)
                for child, child_leds in leds.items():
                    note(_blink(sensor, name, child, child_leds.count))
    finally:
        close_all(opened)
    return out


def _blink(sensor: ImageLedSensor, camera: str, child: str, count: int) -> DeviceReport:
    where = f"{child} seen by {camera}"
    try:
        obs = sensor.observe(child, SwitchingSequence.binary(count))
    except Exception as exc:
        return DeviceReport(child, "LEDs", where, False, {"error": f"{type(exc).__name__}: {exc}"})
    found = int(np.sum(obs.found))
    facts: dict[str, Any] = {"found": f"{found} of {count}", "frames": obs.frames}
    if found:
        facts["pixels"] = ", ".join(
            f"({u:.1f}, {v:.1f})" for (u, v), ok in zip(obs.pixels, obs.found, strict=True) if ok
        )
    missing = sorted({f for f in obs.failures if f is not None})
    if missing:
        facts["not found"] = ", ".join(missing)
    return DeviceReport(child, "LEDs", where, found > 0, facts)
