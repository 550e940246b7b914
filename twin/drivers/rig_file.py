"""The rig file (``rig.toml``): which real device is where, and how to talk to it.

A rig file names each device's driver, its port or URL, the link's settings and the
timeouts; the robots' names and models, which digital outputs drive each child's LEDs,
and each camera's source. The scenario still gives the map, the cameras' nominal poses,
the route, the visits and the instrument's noise; the rig file only the hardware::

    time_scale = 1.0                  # rig seconds per wall second (1 on real hardware)

    [total_station]
    driver = "geocom"                 # Leica GeoCOM (TPS1200, TS/TM/MS series and later)
    port = "/dev/ttyUSB0"             # a serial port, or socket://HOST:PORT
    baud = 115200
    timeout_s = 10.0

    [[robots]]
    name = "parent"                   # as in the scenario
    model = "p3at"
    port = "/dev/ttyS0"               # or socket://HOST:8101
    baud = 9600

    [[robots]]
    name = "child1"
    model = "p3dx"
    port = "socket://10.0.0.21:8101"  # a serial-to-Ethernet bridge
    led_bits = [0, 1, 2, 3]           # DIGOUT bit of each LED, lowest LED first

    [[cameras]]
    name = "cam1"
    source = "rtsp://10.0.0.31/stream1"   # a device index, a V4L2 path, a URL, a file

Loading validates every key as a scenario is validated: an error names the file, the key,
the value and what was expected (:class:`RigFileError`). Times are in rig seconds.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any, Literal

import tomli_w
import yaml
from pydantic import Field

from twin.scenario.errors import ScenarioError, ScenarioIssue
from twin.scenario.loader import read_mapping, validate_model
from twin.scenario.schema import Frozen, Name, Scenario

MAX_SECONDS = 86400.0
"""Longest time a rig file gives (a timeout, a drive), rig seconds: a day."""

MAX_TIME_SCALE = 1000.0
"""Fastest rig a rig file describes, rig seconds per wall second."""

Seconds = Annotated[float, Field(gt=0.0, le=MAX_SECONDS)]
Baud = Annotated[int, Field(gt=0, le=4_000_000)]
Port = Annotated[str, Field(min_length=1, max_length=400)]


class RigFileError(ScenarioError):
    """A rig file failed to parse or validate, or does not fit the scenario."""

    what = "rig file"


class TotalStationDevice(Frozen):
    """The parent's total station.

    Attributes:
        driver: ``geocom``, the only total-station driver. Topcon's GTS series (the paper's
            GTS-820A) has none: its serial command set is not published. A driver for it
            implements :class:`twin.hal.TotalStation` and is added to
            :func:`twin.drivers.build.build_rig`.
        port: a serial port's path, or ``socket://HOST:PORT`` (a serial-to-Ethernet bridge,
            an instrument's own socket).
        baud: the serial line's rate (the instrument's GeoCOM port setting).
        timeout_s: longest wait for an answer, s (a positioning and a measurement included).
    """

    driver: Literal["geocom"] = "geocom"
    port: Port
    baud: Baud = 115200
    timeout_s: Seconds = 10.0


class RobotDevice(Frozen):
    """One Pioneer base, the parent or a child.

    Attributes:
        name: the robot's name in the scenario.
        model: ``p3at`` (the paper's parent) or ``p3dx`` (its children).
        port: a serial port's path, or ``socket://HOST:PORT``.
        baud: the serial line's rate (ARCOS: 9600 by default, 115200 where set so).
        timeout_s: longest time without a server information packet before the robot is
            taken as lost, s.
        max_speed_m_s: the host's speed limit while driving to a goal, m/s.
        max_turn_deg_s: the host's turn-rate limit, deg/s.
        goal_tolerance_m: a drive ends when the odometry is this close to the goal, m.
        drive_timeout_s: a drive that takes longer stops and reports a timeout, s.
        led_bits: a child's LEDs: the digital output bit (0-7) of each LED, lowest LED
            first; empty for the parent.
    """

    name: Name
    model: Literal["p3dx", "p3at"]
    port: Port
    baud: Baud = 9600
    timeout_s: Seconds = 2.0
    max_speed_m_s: Annotated[float, Field(gt=0.0, le=2.0)] = 0.4
    max_turn_deg_s: Annotated[float, Field(gt=0.0, le=360.0)] = 60.0
    goal_tolerance_m: Annotated[float, Field(gt=0.0, le=0.5)] = 0.02
    drive_timeout_s: Seconds = 120.0
    led_bits: tuple[Annotated[int, Field(ge=0, le=7)], ...] = ()


class CameraDevice(Frozen):
    """One fixed camera.

    Attributes:
        name: the camera's name in the scenario.
        driver: ``opencv`` (OpenCV's VideoCapture) or ``genicam`` (a GenTL producer through
            harvesters: ``pip install -e .[genicam]``).
        source: opencv: a device index, a V4L2 path, an RTSP or HTTP URL, a video file, an
            image sequence (``frames/%04d.png``); genicam: the GenTL producer (``.cti``).
        serial: genicam: the camera's serial number (default: the first camera found).
        settle_frames: frames dropped after a capture is asked for, so that the image
            returned was exposed after the LEDs switched.
        frame_interval_s: time between the frames of an LED sequence, s.
        timeout_s: longest wait for a frame, s.
    """

    name: Name
    driver: Literal["opencv", "genicam"] = "opencv"
    source: int | Port
    serial: str | None = None
    settle_frames: Annotated[int, Field(ge=0, le=100)] = 1
    frame_interval_s: Annotated[float, Field(ge=0.0, le=60.0)] = 0.0
    timeout_s: Seconds = 5.0


class EmulatorInfo(Frozen):
    """What ``twin emulate`` adds to the rig file it writes.

    Attributes:
        scenario: the scenario the emulators play.
        truth: a JSON file with the emulated world's truth (each camera's true model in W),
            relative to the rig file; a run against the emulators reports its errors.
    """

    scenario: str
    truth: str


class RigFile(Frozen):
    """A rig file (see the module).

    Attributes:
        name: a label for logs and reports.
        time_scale: rig seconds per wall second: 1 on real hardware; an emulated world may
            run faster, and every timeout, watchdog and period follows it.
        total_station, robots, cameras: the devices.
        emulator: set by ``twin emulate`` only.
        source: the file it was read from.
    """

    name: str = "rig"
    time_scale: Annotated[float, Field(gt=0.0, le=MAX_TIME_SCALE)] = 1.0
    total_station: TotalStationDevice
    robots: Annotated[tuple[RobotDevice, ...], Field(min_length=3)]
    cameras: tuple[CameraDevice, ...] = ()
    emulator: EmulatorInfo | None = None
    source: str | None = None

    def robot(self, name: str) -> RobotDevice:
        """The robot called ``name``."""
        for r in self.robots:
            if r.name == name:
                return r
        raise KeyError(name)


def load_rig_file(path: str | Path) -> RigFile:
    """Read and validate a rig file (TOML; YAML by extension).

    Raises:
        RigFileError: naming the file, each key, its value and what was expected.
    """
    path = Path(path)
    return rig_file_from_dict(read_mapping(path, RigFileError), file=path)


def write_rig_file(
    path: str | Path, rig: Mapping[str, Any], name: str | Path | None = None
) -> RigFile:
    """Write ``rig`` at ``path`` (TOML; YAML for ``.yaml``/``.yml``, as :func:`load_rig_file`
    reads it) and read it back with :func:`load_rig_file`'s own checks: a rig file the
    project writes is one its readers accept.

    Args:
        path: the file to write (for an atomic write, a temporary file whose name ends as
            the rig file's does). rig: the rig file's content.
        name: the rig file's name for the messages (default: ``path``).

    Returns:
        The rig file as read back.

    Raises:
        RigFileError: the content read back is not a valid rig file (naming ``name``, each
            key, its value and what was expected); ``path`` then holds the refused file,
            for the caller to remove.
    """
    path = Path(path)
    yaml_file = path.suffix.lower() in (".yaml", ".yml")
    text = yaml.safe_dump(_plain(rig), sort_keys=False) if yaml_file else tomli_w.dumps(rig)
    path.write_text(text, encoding="utf-8")
    try:
        raw = read_mapping(path, RigFileError)
    except RigFileError as exc:
        raise RigFileError(name or path, exc.issues) from None
    return rig_file_from_dict(raw, file=name or path)


def _plain(value: Any) -> Any:
    """``value`` with its tuples as lists (what ``yaml.safe_dump`` writes)."""
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return value


def rig_file_from_dict(raw: Mapping[str, Any], file: str | Path = "<dict>") -> RigFile:
    """Validate a parsed rig file (see :func:`load_rig_file`)."""
    data = dict(raw)
    data["source"] = str(file)
    rig = validate_model(RigFile, data, file, RigFileError)
    issues = _own_issues(rig)
    if issues:
        raise RigFileError(file, issues)
    return rig


def _own_issues(rig: RigFile) -> list[ScenarioIssue]:
    out: list[ScenarioIssue] = []
    for label, names in (
        ("robots", [r.name for r in rig.robots]),
        ("cameras", [c.name for c in rig.cameras]),
    ):
        for k, name in enumerate(names):
            if name in names[:k]:
                out.append(ScenarioIssue(f"{label}[{k}].name", "repeated", name, "unique names"))
    for k, r in enumerate(rig.robots):
        if len(set(r.led_bits)) != len(r.led_bits):
            out.append(
                ScenarioIssue(
                    f"robots[{k}].led_bits", "a bit used twice", list(r.led_bits), "one bit per LED"
                )
            )
    for k, c in enumerate(rig.cameras):
        if c.driver == "genicam" and not isinstance(c.source, str):
            out.append(
                ScenarioIssue(
                    f"cameras[{k}].source",
                    "not a producer",
                    c.source,
                    "the GenTL producer's .cti path",
                )
            )
    return out


def check_fits(rig: RigFile, scenario: Scenario) -> None:
    """Refuse a rig file that lacks a device the scenario needs.

    Every robot of the scenario has a device of its name; every child as many LED bits as
    the marker has LEDs; every camera of the scenario a camera device.

    Raises:
        RigFileError: naming each problem.
    """
    issues: list[ScenarioIssue] = []
    names = {r.name: k for k, r in enumerate(rig.robots)}
    leds = len(scenario.marker.leds)
    for robot in scenario.robots.all:
        if robot.name not in names:
            issues.append(
                ScenarioIssue(
                    "robots",
                    f"no device for robot {robot.name!r}",
                    sorted(names),
                    f"a [[robots]] entry named {robot.name!r}",
                )
            )
    for child in scenario.robots.children:
        k = names.get(child.name)
        if k is not None and len(rig.robots[k].led_bits) != leds:
            issues.append(
                ScenarioIssue(
                    f"robots[{k}].led_bits",
                    f"child {child.name!r} needs one bit per LED",
                    list(rig.robots[k].led_bits),
                    f"{leds} bits (the marker has {leds} LEDs)",
                )
            )
    cams = [c.name for c in rig.cameras]
    for camera in scenario.cameras:
        if camera.name not in cams:
            issues.append(
                ScenarioIssue(
                    "cameras",
                    f"no device for camera {camera.name!r}",
                    cams,
                    f"a [[cameras]] entry named {camera.name!r}",
                )
            )
    if issues:
        raise RigFileError(rig.source or "<rig>", issues)
