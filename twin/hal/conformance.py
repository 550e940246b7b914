"""Does a rig keep the interface's promises? :func:`check_rig`, in the spirit of
Gymnasium's ``check_env``: run it on any implementation of :mod:`twin.hal` (the twin at
either fidelity, real drivers) before trusting a campaign to it.

What is checked:

- the rig has what the campaign needs (:func:`twin.hal.structure.check_rig_structure`);
- every reading is a frozen dataclass of the documented type with a finite timestamp in
  seconds that lies between the clock's readings before and after the call, and values in
  SI units: finite, except where :mod:`twin.hal.readings` documents a NaN (an LED not
  found, the yaw of a drive asked without one), angles in radians within their range,
  pixels inside the image, a shot within the instrument's range (and, where the caller
  knows where a prism is, within a few centimetres of it: a shot in millimetres is
  refused);
- the clock never goes back;
- a device raises only the errors :data:`twin.hal.devices.DOCUMENTED_ERRORS` lists;
- ``close()`` twice is safe.

The check drives each base to where it stands (a drive of zero length, with and without a
goal heading), corrects its pose estimate with the pose it reports, switches every child's
LEDs, runs one LED sequence for each camera and child, captures one image per camera, and
points the instrument at each target it is given. It closes the rig at the end (unless
``close=False``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable
from typing import Any, TypeVar

import numpy as np
from numpy.typing import ArrayLike

from calib.detection.sequence import SwitchingSequence
from twin.hal.devices import (
    DOCUMENTED_ERRORS,
    Camera,
    LedSensor,
    MarkerLeds,
    MobileBase,
)
from twin.hal.readings import (
    CameraImage,
    DriveResult,
    DriveStatus,
    LedObservation,
    LedSwitch,
    OdometryReading,
    TiltReading,
    TotalStationMeasurement,
)
from twin.hal.rig import Rig
from twin.hal.structure import RigCheckError, check_rig_structure

TIME_SLACK = 1e-9
"""Rounding allowed when a reading's timestamp is compared with the clock, s."""

PRISM_TOLERANCE = 0.05
"""A shot aimed at a known prism must land this close to it, m (a prism's housing, and the
instrument's noise many times over)."""

MAX_TILT = 0.5 * math.pi
"""Largest inclination an inclination sensor can report, rad."""

PIXEL_MARGIN = 0.5
"""An LED's pixel may lie this far outside the image's pixel centres, px (the edge of the
outermost pixels)."""

T = TypeVar("T")


class Raised:
    """What :meth:`_Checker.call` returns for a call that raised."""


RAISED = Raised()


@dataclasses.dataclass
class RigCheckReport:
    """What :func:`check_rig` exercised.

    Attributes:
        shots: shots the instrument measured. drives: drives the bases made.
        observations: LED sequences observed. leds_found: LEDs found in them.
        images: images captured. documented_errors: calls that raised an error the
            interface documents (a lost lock, say): allowed, and counted.
    """

    shots: int = 0
    drives: int = 0
    observations: int = 0
    leds_found: int = 0
    images: int = 0
    documented_errors: int = 0


class _Checker:
    """One run of the checks: the rig, its clock's last reading, the problems found and
    what was exercised."""

    def __init__(self, rig: Rig) -> None:
        self.rig = rig
        self.problems: list[str] = []
        self.last_time = -math.inf
        self.report = RigCheckReport()

    def fail(self, where: str, message: str) -> None:
        self.problems.append(f"{where}: {message}")

    def now(self, where: str) -> float:
        """The clock's time, checked: finite, >= 0, never before an earlier reading."""
        t = self.call("Clock.now", f"{where} (clock)", self.rig.clock.now)
        if not isinstance(t, int | float) or not math.isfinite(t):
            self.fail(f"{where} (clock)", f"Clock.now() must return finite seconds, got {t!r}")
            return self.last_time
        if t < 0.0:
            self.fail(f"{where} (clock)", f"the clock reads {t} s, before the rig started")
        if t < self.last_time - TIME_SLACK:
            self.fail(f"{where} (clock)", f"the clock went back from {self.last_time} s to {t} s")
        self.last_time = max(self.last_time, float(t))
        return float(t)

    def call(self, method: str, where: str, fn: Callable[..., T], *args: Any) -> T | Raised:
        """``fn(*args)``, or :data:`RAISED` if it raised: an error the interface documents
        for ``method`` is allowed, any other is a problem."""
        try:
            return fn(*args)
        except DOCUMENTED_ERRORS[method]:
            self.report.documented_errors += 1
            return RAISED
        except Exception as exc:
            allowed = ", ".join(e.__name__ for e in DOCUMENTED_ERRORS[method]) or "none"
            self.fail(
                where,
                f"{method} raised {type(exc).__name__}: {exc} (twin.hal documents {allowed})",
            )
            return RAISED

    def reading(self, where: str, value: object, kind: type, before: float, after: float) -> bool:
        """Whether ``value`` is a frozen ``kind`` with a finite timestamp between the clock
        readings ``before`` and ``after`` (noting what is not)."""
        if not isinstance(value, kind):
            self.fail(where, f"expected a {kind.__name__}, got {type(value).__name__}")
            return False
        params = getattr(type(value), "__dataclass_params__", None)
        if not dataclasses.is_dataclass(value) or params is None or not params.frozen:
            self.fail(where, f"a {kind.__name__} must be a frozen dataclass")
            return False
        t = getattr(value, "timestamp", None)
        if not isinstance(t, int | float) or not math.isfinite(t):
            self.fail(where, f"the timestamp must be finite seconds, got {t!r}")
            return False
        if not before - TIME_SLACK <= t <= after + TIME_SLACK:
            self.fail(
                where,
                f"timestamp {t} s lies outside the call ({before} s to {after} s on the "
                "rig's clock)",
            )
        return True


def check_rig(
    rig: Rig,
    *,
    prisms_level: ArrayLike | None = None,
    cameras: Iterable[str] = (),
    drive: bool = True,
    observe: bool = True,
    close: bool = True,
) -> RigCheckReport:
    """Check that ``rig`` keeps the promises of :mod:`twin.hal` (see the module).

    Args:
        rig: the rig to check.
        prisms_level: (K, 3) where prisms stand in the instrument's levelled frame, m, if
            the caller knows (surveyed marks; the truth, in a simulation): the instrument
            is pointed at each and a shot that locks must land within
            :data:`PRISM_TOLERANCE` of one. Without them the instrument is pointed at each
            child's reported position, where it may find no prism (a documented error).
        cameras: cameras the campaign will calibrate: each needs an LED sensor.
        drive: drive each base to where it stands (a drive of zero length).
        observe: run one LED sequence per camera and child.
        close: close the rig twice at the end (which must be safe).

    Returns:
        What the check exercised.

    Raises:
        RigCheckError: naming every problem found.
    """
    check_rig_structure(rig, cameras)
    check = _Checker(rig)
    check.now("start")
    _check_total_station(check, prisms_level)
    poses = {name: _check_base(check, base, drive) for name, base in _bases(rig)}
    if prisms_level is None:
        _check_shots_at_children(check, poses)
    for child, leds in rig.leds.items():
        _check_leds(check, child, leds)
    if observe:
        for sensor in rig.led_sensors.values():
            for child, leds in rig.leds.items():
                _check_observation(check, sensor, child, leds.count)
    for camera in rig.cameras.values():
        _check_capture(check, camera)
    if close:
        for attempt in ("first", "second"):
            try:
                rig.close()
            except Exception as exc:
                check.fail("Rig.close", f"the {attempt} close() raised {type(exc).__name__}: {exc}")
    if check.problems:
        raise RigCheckError(
            f"the rig breaks the interface ({len(check.problems)} problems):\n- "
            + "\n- ".join(check.problems)
        )
    return check.report


def _bases(rig: Rig) -> list[tuple[str, MobileBase]]:
    return [(rig.parent.name, rig.parent), *rig.children.items()]


def _check_total_station(check: _Checker, prisms_level: ArrayLike | None) -> None:
    station = check.rig.total_station
    where = "TotalStation.read_inclination"
    before = check.now(where)
    tilt = check.call(where, where, station.read_inclination)
    after = check.now(where)
    if tilt is not RAISED and check.reading(where, tilt, TiltReading, before, after):
        for name in ("roll", "pitch"):
            value = getattr(tilt, name)
            if not abs(value) <= MAX_TILT:
                check.fail(where, f"{name} {value} must be an inclination in rad")
    if prisms_level is None:
        return
    targets = np.asarray(prisms_level, dtype=float).reshape(-1, 3)
    for k, target in enumerate(targets):
        shot = _shoot(check, target, f"TotalStation shot at prism {k}")
        if shot is None:
            continue
        landed = shot.to_cartesian()
        miss = float(np.min(np.linalg.norm(targets - landed, axis=1)))
        if miss > PRISM_TOLERANCE:
            check.fail(
                f"TotalStation shot at prism {k}",
                f"the shot lands {miss:.3g} m from the nearest known prism: are its distance "
                "and angles in m and rad?",
            )


def _shoot(check: _Checker, target: np.ndarray, where: str) -> TotalStationMeasurement | None:
    station = check.rig.total_station
    if check.call("TotalStation.point", where, station.point, target) is RAISED:
        return None
    before = check.now(where)
    shot = check.call("TotalStation.measure", where, station.measure)
    after = check.now(where)
    if shot is RAISED or not check.reading(where, shot, TotalStationMeasurement, before, after):
        return None
    assert isinstance(shot, TotalStationMeasurement)
    check.report.shots += 1
    spec = station.spec
    if not spec.range_min - 1e-9 <= shot.distance <= spec.range_max + 1e-9:
        check.fail(
            where,
            f"distance {shot.distance} lies outside the instrument's range "
            f"{spec.range_min}-{spec.range_max} m: is it in metres?",
        )
    return shot


def _check_shots_at_children(check: _Checker, poses: dict[str, OdometryReading | None]) -> None:
    """Point the instrument at each child's reported place (at the instrument's height):
    a shot or a documented error, nothing else."""
    parent = poses.get(check.rig.parent.name)
    if parent is None:
        return
    c, s = math.cos(parent.yaw), math.sin(parent.yaw)
    for name in check.rig.children:
        pose = poses.get(name)
        if pose is None:
            continue
        dx, dy = pose.x - parent.x, pose.y - parent.y
        target = np.array([c * dx + s * dy, -s * dx + c * dy, 0.0])
        if np.linalg.norm(target) > 0:
            _shoot(check, target, f"TotalStation shot towards {name}")


def _check_base(check: _Checker, base: MobileBase, drive: bool) -> OdometryReading | None:
    name = base.name
    odo = _check_odometry(check, base, f"MobileBase {name!r}.odometry")
    if odo is None:
        return None
    if drive:
        for goal_yaw in (None, odo.yaw):
            heading = "" if goal_yaw is None else " with a goal heading"
            where = f"MobileBase {name!r}.drive_to{heading}"
            before = check.now(where)
            result = check.call(
                "MobileBase.drive_to", where, base.drive_to, [odo.x, odo.y], goal_yaw
            )
            after = check.now(where)
            if result is RAISED or not check.reading(where, result, DriveResult, before, after):
                continue
            assert isinstance(result, DriveResult)
            check.report.drives += 1
            _check_drive_result(check, where, result, name, goal_yaw)
    where = f"MobileBase {name!r}.set_pose"
    now = _check_odometry(check, base, f"MobileBase {name!r}.odometry") or odo
    check.call("MobileBase.set_pose", where, base.set_pose, now.x, now.y, now.yaw)
    after = _check_odometry(check, base, f"MobileBase {name!r}.odometry after set_pose")
    if after is not None and math.hypot(after.x - now.x, after.y - now.y) > 1e-6:
        check.fail(
            where, f"set_pose({now.x}, {now.y}) then odometry() reads ({after.x}, {after.y})"
        )
    return after


def _check_odometry(check: _Checker, base: MobileBase, where: str) -> OdometryReading | None:
    before = check.now(where)
    odo = check.call("MobileBase.odometry", where, base.odometry)
    after = check.now(where)
    if odo is RAISED or not check.reading(where, odo, OdometryReading, before, after):
        return None
    assert isinstance(odo, OdometryReading)
    if odo.robot != base.name:
        check.fail(where, f"the reading is of robot {odo.robot!r}")
    if not -math.pi - 1e-9 <= odo.yaw <= math.pi + 1e-9:
        check.fail(where, f"yaw {odo.yaw} must be in rad within [-pi, pi]")
    return odo


def _check_drive_result(
    check: _Checker, where: str, result: DriveResult, name: str, goal_yaw: float | None
) -> None:
    if result.robot != name:
        check.fail(where, f"the result is of robot {result.robot!r}")
    if not isinstance(result.status, DriveStatus):
        check.fail(where, f"status must be a DriveStatus, got {result.status!r}")
    goal = np.asarray(result.goal, dtype=float)
    if goal.shape != (3,) or not np.all(np.isfinite(goal[:2])):
        check.fail(where, f"goal must be finite (x, y, yaw), got {result.goal!r}")
    elif goal_yaw is None and not math.isnan(goal[2]):
        check.fail(where, f"a drive asked without a heading has goal yaw NaN, got {goal[2]}")
    elif goal_yaw is not None and not math.isfinite(goal[2]):
        check.fail(where, "a drive asked with a heading has a finite goal yaw")
    if not (math.isfinite(result.duration) and result.duration >= 0.0):
        check.fail(where, f"duration must be finite seconds >= 0, got {result.duration}")
    if not isinstance(result.odometry, OdometryReading) or result.odometry.robot != name:
        check.fail(where, "odometry must be the base's own OdometryReading")


def _check_leds(check: _Checker, child: str, leds: MarkerLeds) -> None:
    for flag in (True, False):
        where = f"MarkerLeds {child!r}.switch({'on' if flag else 'off'})"
        before = check.now(where)
        event = check.call("MarkerLeds.switch", where, leds.switch, [flag] * leds.count)
        after = check.now(where)
        if event is RAISED or not check.reading(where, event, LedSwitch, before, after):
            continue
        assert isinstance(event, LedSwitch)
        if event.child != child:
            check.fail(where, f"the switch is of child {event.child!r}")
        if tuple(event.on) != (flag,) * leds.count:
            check.fail(where, f"switched {event.on}, asked {(flag,) * leds.count}")


def _check_observation(check: _Checker, sensor: LedSensor, child: str, count: int) -> None:
    where = f"LedSensor {sensor.camera!r}.observe({child!r})"
    sequence = SwitchingSequence.binary(count)
    before = check.now(where)
    obs = check.call("LedSensor.observe", where, sensor.observe, child, sequence)
    after = check.now(where)
    if obs is RAISED or not check.reading(where, obs, LedObservation, before, after):
        return
    assert isinstance(obs, LedObservation)
    check.report.observations += 1
    check.report.leds_found += sum(f is None for f in obs.failures)
    if (obs.camera, obs.child) != (sensor.camera, child):
        check.fail(where, f"the observation is of camera {obs.camera!r}, child {obs.child!r}")
    pixels, sigma = np.asarray(obs.pixels), np.asarray(obs.sigma_px)
    if pixels.shape != (count, 2) or sigma.shape != (count,) or len(obs.failures) != count:
        check.fail(where, f"expected {count} LEDs, got pixels of shape {pixels.shape}")
        return
    width, height = sensor.image_size
    for k, failure in enumerate(obs.failures):
        if failure is not None:
            if np.any(np.isfinite(pixels[k])) or np.isfinite(sigma[k]):
                check.fail(where, f"LED {k} was not found ({failure}) but has a pixel")
            continue
        if not (np.all(np.isfinite(pixels[k])) and math.isfinite(sigma[k]) and sigma[k] > 0):
            check.fail(where, f"LED {k} was found: its pixel and sigma_px must be finite")
            continue
        u, v = pixels[k]
        inside = -PIXEL_MARGIN <= u <= width - 1 + PIXEL_MARGIN
        inside &= -PIXEL_MARGIN <= v <= height - 1 + PIXEL_MARGIN
        if not inside:
            check.fail(where, f"LED {k} at ({u:.1f}, {v:.1f}) px lies outside the image")
    if not isinstance(obs.frames, int) or obs.frames < 0:
        check.fail(where, f"frames must be a count, got {obs.frames!r}")


def _check_capture(check: _Checker, camera: Camera) -> None:
    where = f"Camera {camera.name!r}.capture"
    before = check.now(where)
    image = check.call("Camera.capture", where, camera.capture)
    after = check.now(where)
    if image is RAISED or not check.reading(where, image, CameraImage, before, after):
        return
    assert isinstance(image, CameraImage)
    check.report.images += 1
    width, height = camera.image_size
    a = np.asarray(image.image)
    if a.shape[:2] != (height, width):
        check.fail(where, f"the image is {a.shape}, the camera's size is {width} x {height}")
    if a.dtype not in (np.uint8, np.uint16):
        check.fail(where, f"the image must be uint8 or uint16, got {a.dtype}")
