"""Build a rig of real devices from a rig file: the one place where a driver is chosen.

The rig is a :class:`twin.hal.Rig` like the simulated one: the campaign runs on it
unchanged. The scenario gives what the hardware does not say: each robot's start pose in
W, the marker's LED heights, the instrument's noise (by which the campaign weighs its
shots).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from twin.closing import Closing
from twin.drivers.clock import WallClock
from twin.drivers.rig_file import (
    CameraDevice,
    RigFile,
    RobotDevice,
    TotalStationDevice,
    check_fits,
)
from twin.hal.devices import Camera, LedSensor, MarkerLeds, MobileBase, TotalStation
from twin.hal.errors import DeviceLostError
from twin.hal.led_sensing import ImageLedSensor
from twin.hal.rig import Rig
from twin.scenario.schema import Noise, Scenario


class DeviceConnectError(RuntimeError):
    """A device of the rig file could not be opened: the message names it, its port or
    source and why. Every device opened before it is closed again."""


@dataclass
class DriverRig(Closing):
    """A rig of real devices, and what each said about itself when it was opened.

    Attributes:
        rig: the devices, as the campaign sees them.
        identities: per device (``total_station``, each robot, each camera), what it
            reported: names, serial numbers, battery, resolution and frame rate.
        connections: the robots' links, closed with the rig.
    """

    rig: Rig
    identities: dict[str, dict[str, Any]] = field(default_factory=dict)
    connections: list[Closing] = field(default_factory=list)

    def close(self) -> None:
        """Stop and close every device (robots first stopped by their bases' close)."""
        try:
            self.rig.close()
        finally:
            for c in self.connections:
                c.close()


def build_rig(rig_file: RigFile, scenario: Scenario) -> DriverRig:
    """Open every device of ``rig_file`` for ``scenario``'s campaign.

    Raises:
        twin.drivers.rig_file.RigFileError: the rig file lacks a device the scenario needs.
        DeviceConnectError: a device could not be opened (the message names it).
        ImportError: a driver's optional package is missing (the message says which extra
            installs it).
    """
    check_fits(rig_file, scenario)
    clock = WallClock(rig_file.time_scale)
    opened: list[Closing] = []
    identities: dict[str, dict[str, Any]] = {}

    def open_device(label: str, where: str, make: Callable[[], Any], key: str | None = None) -> Any:
        """``make()``, kept to be closed; with ``key``, its identity recorded under it."""
        try:
            device = make()
            opened.append(device)
            if key is not None:
                identities[key] = identify(device)
        except ImportError:
            raise
        except DeviceLostError as exc:
            # Its message names the device and, where given, its link already.
            said = str(exc) if exc.link else f"{label} at {where}: {exc}"
            raise DeviceConnectError(said) from exc
        except Exception as exc:
            raise DeviceConnectError(f"{label} at {where}: {type(exc).__name__}: {exc}") from exc
        return device

    try:
        return _build(rig_file, scenario, clock, open_device, identities)
    except BaseException:
        close_all(opened)
        raise


def _build(
    rig_file: RigFile,
    scenario: Scenario,
    clock: WallClock,
    open_device: Callable[..., Any],
    identities: dict[str, dict[str, Any]],
) -> DriverRig:
    """The devices of :func:`build_rig`, each opened through ``open_device``."""
    station = open_device(
        "total station",
        rig_file.total_station.port,
        lambda: open_total_station(rig_file.total_station, clock, scenario.noise),
        "total_station",
    )
    bases: dict[str, MobileBase] = {}
    leds: dict[str, MarkerLeds] = {}
    connections = []
    children = {c.name for c in scenario.robots.children}
    for robot in scenario.robots.all:
        device = rig_file.robot(robot.name)
        label = f"robot {robot.name!r}"
        connection = open_device(
            label, device.port, lambda d=device: open_connection(d, clock), robot.name
        )
        connections.append(connection)
        start = (float(robot.start_xy[0]), float(robot.start_xy[1]), robot.start_yaw)
        bases[robot.name] = open_device(
            label, device.port, lambda c=connection, d=device, s=start: open_base(c, d, s)
        )
        if robot.name in children:
            leds[robot.name] = open_device(
                f"LEDs of {robot.name!r}",
                device.port,
                lambda c=connection, d=device: open_leds(c, d),
            )
    cameras: dict[str, Camera] = {}
    sensors: dict[str, LedSensor] = {}
    led_line = [float(p[2]) for p in scenario.marker.leds]
    for cam in scenario.cameras:
        device_cam = next(c for c in rig_file.cameras if c.name == cam.name)
        camera = open_device(
            f"camera {cam.name!r}",
            str(device_cam.source),
            lambda d=device_cam: open_camera(d, clock),
            cam.name,
        )
        cameras[cam.name] = camera
        sensors[cam.name] = ImageLedSensor(
            camera,
            leds,
            clock,
            frame_interval=device_cam.frame_interval_s,
            led_line=led_line,
        )
    parent = scenario.robots.parent.name
    rig = Rig(
        clock=clock,
        total_station=station,
        parent=bases[parent],
        children={c.name: bases[c.name] for c in scenario.robots.children},
        leds=leds,
        led_sensors=sensors,
        cameras=cameras,
    )
    return DriverRig(rig=rig, identities=identities, connections=connections)


def check_drivers(rig_file: RigFile) -> None:
    """Check, without opening anything, that every driver the rig file names can be loaded.

    Raises:
        ImportError: a driver's optional package is missing (the message says which extra
            installs it).
    """
    if any(c.driver == "genicam" for c in rig_file.cameras):
        from twin.drivers.genicam import harvester_class

        harvester_class()


def close_all(devices: list[Closing]) -> None:
    """Close ``devices``, last opened first, whatever each raises."""
    for d in reversed(devices):
        with contextlib.suppress(Exception):
            d.close()


def identify(device: Any) -> dict[str, Any]:
    """What a driver says about its device (its ``identify()``), or nothing."""
    identify = getattr(device, "identify", None)
    return dict(identify()) if callable(identify) else {}


def open_total_station(device: TotalStationDevice, clock: WallClock, noise: Noise) -> TotalStation:
    """The instrument of ``device``, advertising ``noise`` (the scenario's, by which the
    campaign weighs its shots)."""
    if device.driver == "geocom":
        from twin.drivers.geocom import GeoComTotalStation

        return GeoComTotalStation(
            device.port,
            clock=clock,
            spec=noise.total_station.spec(),
            inclinometer=noise.inclinometer.spec(),
            baud=device.baud,
            timeout_s=device.timeout_s,
        )
    raise ValueError(f"no total-station driver {device.driver!r}")


def open_connection(device: RobotDevice, clock: WallClock) -> Closing:
    """The ARCOS link of one Pioneer (synchronised, opened, motors enabled)."""
    from twin.drivers.arcos.connection import PioneerConnection

    return PioneerConnection(
        device.port,
        model=device.model,
        clock=clock,
        baud=device.baud,
        timeout_s=device.timeout_s,
        name=device.name,
    )


def open_base(
    connection: Any, device: RobotDevice, start: tuple[float, float, float]
) -> MobileBase:
    """The base on ``connection``, at ``start`` (x m, y m, yaw rad in W) when it opened."""
    from twin.drivers.arcos.base import ArcosBase

    return ArcosBase(
        connection,
        name=device.name,
        start_pose=start,
        max_speed=device.max_speed_m_s,
        max_turn_rate=math.radians(device.max_turn_deg_s),
        goal_tolerance=device.goal_tolerance_m,
        drive_timeout_s=device.drive_timeout_s,
    )


def open_leds(connection: Any, device: RobotDevice) -> MarkerLeds:
    """A child's LEDs on the digital outputs ``device.led_bits``."""
    from twin.drivers.arcos.leds import ArcosLeds

    return ArcosLeds(connection, child=device.name, bits=device.led_bits)


def open_camera(device: CameraDevice, clock: WallClock) -> Camera:
    """The camera of ``device`` (OpenCV or GenICam)."""
    if device.driver == "genicam":
        from twin.drivers.genicam import GenICamCamera

        return GenICamCamera(
            str(device.source),
            name=device.name,
            clock=clock,
            serial=device.serial,
            timeout_s=device.timeout_s,
        )
    from twin.drivers.camera import OpenCvCamera

    return OpenCvCamera(
        device.source,
        name=device.name,
        clock=clock,
        settle_frames=device.settle_frames,
        timeout_s=device.timeout_s,
    )
