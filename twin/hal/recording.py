"""Every reading that passes through the interface, recorded as it arrives.

:func:`recorded` wraps a :class:`Rig`'s devices so that each reading, each command that
changes the world (a drive, an LED switch, a pose fix) and each device failure is handed
to a :class:`Recorder` before the caller sees it. Images are not recorded (the LED
observations made from them are).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

from numpy.typing import ArrayLike

from calib.detection.sequence import SwitchingSequence
from twin.hal.devices import Clock, LedSensor, MarkerLeds, MobileBase, TotalStation
from twin.hal.readings import (
    DriveResult,
    Event,
    LedObservation,
    LedSwitch,
    OdometryReading,
    TiltReading,
    TotalStationMeasurement,
)
from twin.hal.rig import Rig
from twin.instruments.errors import InstrumentError
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec


class Recorder(Protocol):
    """Where records go: ``record(topic, record, timestamp)``."""

    def record(self, topic: str, record: object, timestamp: float) -> None: ...


class _RecordedClock(Clock):
    def __init__(self, inner: Clock) -> None:
        self.inner = inner

    def now(self) -> float:
        return self.inner.now()

    def sleep(self, seconds: float) -> None:
        self.inner.sleep(seconds)

    def close(self) -> None:
        self.inner.close()


class _RecordedTotalStation(TotalStation):
    def __init__(self, inner: TotalStation, recorder: Recorder, clock: Clock) -> None:
        self.inner, self._rec, self._clock = inner, recorder, clock
        self._aim: list[float] = []

    @property
    def spec(self) -> TotalStationSpec:
        return self.inner.spec

    @property
    def inclinometer(self) -> InclinometerSpec | None:
        return self.inner.inclinometer

    def point(self, target_level: ArrayLike) -> None:
        self._aim = [float(x) for x in target_level]  # type: ignore[union-attr]
        self.inner.point(target_level)

    def measure(self) -> TotalStationMeasurement:
        try:
            shot = self.inner.measure()
        except InstrumentError as exc:
            event = Event(
                self._clock.now(),
                exc.reason.value,
                str(exc),
                {"aim_level": self._aim, **_plain(exc.details)},
            )
            self._rec.record("/total_station/failure", event, event.timestamp)
            raise
        self._rec.record("/total_station/shot", shot, shot.timestamp)
        return shot

    def read_inclination(self) -> TiltReading:
        reading = self.inner.read_inclination()
        self._rec.record("/total_station/inclination", reading, reading.timestamp)
        return reading

    def close(self) -> None:
        self.inner.close()


class _RecordedBase(MobileBase):
    def __init__(self, inner: MobileBase, recorder: Recorder, clock: Clock) -> None:
        self.inner, self._rec, self._clock = inner, recorder, clock

    @property
    def name(self) -> str:
        return self.inner.name

    def drive_to(self, goal_xy: ArrayLike, goal_yaw: float | None = None) -> DriveResult:
        result = self.inner.drive_to(goal_xy, goal_yaw)
        self._rec.record(f"/base/{self.name}/drive", result, result.timestamp)
        return result

    def odometry(self) -> OdometryReading:
        reading = self.inner.odometry()
        self._rec.record(f"/base/{self.name}/odometry", reading, reading.timestamp)
        return reading

    def set_pose(self, x: float, y: float, yaw: float) -> None:
        self.inner.set_pose(x, y, yaw)
        t = self._clock.now()
        fix = OdometryReading(self.name, t, float(x), float(y), float(yaw))
        self._rec.record(f"/base/{self.name}/set_pose", fix, t)

    def close(self) -> None:
        self.inner.close()


class _RecordedLeds(MarkerLeds):
    def __init__(self, inner: MarkerLeds, recorder: Recorder) -> None:
        self.inner, self._rec = inner, recorder

    @property
    def child(self) -> str:
        return self.inner.child

    @property
    def count(self) -> int:
        return self.inner.count

    def switch(self, on: Sequence[bool]) -> LedSwitch:
        event = self.inner.switch(on)
        self._rec.record(f"/leds/{self.child}", event, event.timestamp)
        return event

    def close(self) -> None:
        self.inner.close()


class _RecordedLedSensor(LedSensor):
    def __init__(self, inner: LedSensor, recorder: Recorder) -> None:
        self.inner, self._rec = inner, recorder

    @property
    def camera(self) -> str:
        return self.inner.camera

    @property
    def image_size(self) -> tuple[int, int]:
        return self.inner.image_size

    def observe(self, child: str, sequence: SwitchingSequence) -> LedObservation:
        obs = self.inner.observe(child, sequence)
        self._rec.record(f"/camera/{self.camera}/leds", obs, obs.timestamp)
        return obs

    def close(self) -> None:
        self.inner.close()


def _plain(details: object) -> dict:
    if not isinstance(details, dict):
        return {}
    out = {}
    for k, v in details.items():
        out[str(k)] = v.tolist() if hasattr(v, "tolist") else v
    return out


def recorded(rig: Rig, recorder: Recorder) -> Rig:
    """The same rig with every reading, command and device failure recorded.

    The LED sensors built on the rig's own LEDs keep switching the unrecorded LEDs (a
    sequence's switches are implied by its observation); everything else goes through the
    recorder. Closing the returned rig closes the devices.
    """
    clock = _RecordedClock(rig.clock)
    return Rig(
        clock=clock,
        total_station=_RecordedTotalStation(rig.total_station, recorder, clock),
        parent=_RecordedBase(rig.parent, recorder, clock),
        children={n: _RecordedBase(b, recorder, clock) for n, b in rig.children.items()},
        leds={n: _RecordedLeds(led, recorder) for n, led in rig.leds.items()},
        led_sensors={n: _RecordedLedSensor(s, recorder) for n, s in rig.led_sensors.items()},
        cameras=dict(rig.cameras),
        timings=rig.timings,
    )
