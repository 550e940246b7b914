"""Devices that wrap other devices: every call goes to the inner device unless a subclass
overrides it, as Gymnasium's wrappers wrap an environment.

A wrapper changes what one device does without the campaign or the backend knowing: the
recorder (:mod:`.recording`) writes every reading to a log, a test injects a fault (a
child pushed while another drives, a heading knocked off after a turn), a check counts the
calls. :func:`wrapped` returns a rig with some of its devices wrapped.

Closing a wrapper closes the device it wraps.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Generic, TypeVar

from numpy.typing import ArrayLike

from calib.detection.sequence import SwitchingSequence
from twin.closing import Closing
from twin.hal.devices import Camera, Clock, LedSensor, MarkerLeds, MobileBase, TotalStation
from twin.hal.readings import (
    CameraImage,
    DriveResult,
    LedObservation,
    LedSwitch,
    OdometryReading,
    TiltReading,
    TotalStationMeasurement,
)
from twin.hal.rig import Rig
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec

_Inner = TypeVar("_Inner", bound=Closing)


class _Wrapper(Generic[_Inner]):
    """Holds the wrapped device, ``inner``; closing the wrapper closes it."""

    def __init__(self, inner: _Inner) -> None:
        self.inner = inner

    def close(self) -> None:
        self.inner.close()


class ClockWrapper(_Wrapper[Clock], Clock):
    """A clock that passes every call to ``inner``."""

    def now(self) -> float:
        return self.inner.now()

    def sleep(self, seconds: float) -> None:
        self.inner.sleep(seconds)


class TotalStationWrapper(_Wrapper[TotalStation], TotalStation):
    """A total station that passes every call to ``inner``."""

    @property
    def spec(self) -> TotalStationSpec:
        return self.inner.spec

    @property
    def inclinometer(self) -> InclinometerSpec | None:
        return self.inner.inclinometer

    def point(self, target_level: ArrayLike) -> None:
        self.inner.point(target_level)

    def measure(self) -> TotalStationMeasurement:
        return self.inner.measure()

    def read_inclination(self) -> TiltReading:
        return self.inner.read_inclination()


class MobileBaseWrapper(_Wrapper[MobileBase], MobileBase):
    """A mobile base that passes every call to ``inner``."""

    @property
    def name(self) -> str:
        return self.inner.name

    def drive_to(self, goal_xy: ArrayLike, goal_yaw: float | None = None) -> DriveResult:
        return self.inner.drive_to(goal_xy, goal_yaw)

    def odometry(self) -> OdometryReading:
        return self.inner.odometry()

    def set_pose(self, x: float, y: float, yaw: float) -> None:
        self.inner.set_pose(x, y, yaw)


class MarkerLedsWrapper(_Wrapper[MarkerLeds], MarkerLeds):
    """A child's LEDs that pass every call to ``inner``."""

    @property
    def child(self) -> str:
        return self.inner.child

    @property
    def count(self) -> int:
        return self.inner.count

    def switch(self, on: Sequence[bool]) -> LedSwitch:
        return self.inner.switch(on)


class LedSensorWrapper(_Wrapper[LedSensor], LedSensor):
    """An LED sensor that passes every call to ``inner``."""

    @property
    def camera(self) -> str:
        return self.inner.camera

    @property
    def image_size(self) -> tuple[int, int]:
        return self.inner.image_size

    def observe(self, child: str, sequence: SwitchingSequence) -> LedObservation:
        return self.inner.observe(child, sequence)

    def last_image(self) -> CameraImage | None:
        return self.inner.last_image()


D = TypeVar("D")


def _same(device: D) -> D:
    return device


def wrapped(
    rig: Rig,
    *,
    clock: Callable[[Clock], Clock] = _same,
    total_station: Callable[[TotalStation], TotalStation] = _same,
    base: Callable[[MobileBase], MobileBase] = _same,
    leds: Callable[[MarkerLeds], MarkerLeds] = _same,
    led_sensor: Callable[[LedSensor], LedSensor] = _same,
    camera: Callable[[Camera], Camera] = _same,
) -> Rig:
    """The same rig with its devices passed through the given functions (each takes a
    device and returns it or its wrapper; ``base`` is applied to the parent and to every
    child). The rig's timings are shared. Closing the returned rig closes the devices."""
    return Rig(
        clock=clock(rig.clock),
        total_station=total_station(rig.total_station),
        parent=base(rig.parent),
        children={n: base(b) for n, b in rig.children.items()},
        leds={n: leds(d) for n, d in rig.leds.items()},
        led_sensors={n: led_sensor(s) for n, s in rig.led_sensors.items()},
        cameras={n: camera(c) for n, c in rig.cameras.items()},
        timings=rig.timings,
    )
