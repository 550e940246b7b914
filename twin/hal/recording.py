"""Every reading that passes through the interface, recorded as it arrives.

:func:`recorded` wraps a :class:`Rig`'s devices so that each reading, each command that
changes the world (a drive, an LED switch, a pose fix) and each device failure is handed
to a :class:`Recorder` before the caller sees it. Images are not records (the LED
observations made from them are); a recorder that takes them is handed the image of each
LED observation. The recording devices are wrappers
(:mod:`twin.hal.wrappers`).
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
from twin.hal.wrappers import (
    ClockWrapper,
    LedSensorWrapper,
    MarkerLedsWrapper,
    MobileBaseWrapper,
    TotalStationWrapper,
    wrapped,
)
from twin.instruments.errors import InstrumentError


class Recorder(Protocol):
    """Where records go: ``record(topic, record, timestamp)``.

    A recorder that also has ``image(camera, image, timestamp)`` is handed, after each LED
    observation's record, the image the LEDs were found in (a
    :class:`~twin.hal.readings.CameraImage`: :meth:`~twin.hal.devices.LedSensor.last_image`)
    at the observation's time: images are not records; a recorder without ``image`` gets
    none.
    """

    def record(self, topic: str, record: object, timestamp: float) -> None: ...


class _RecordedTotalStation(TotalStationWrapper):
    def __init__(self, inner: TotalStation, recorder: Recorder, clock: Clock) -> None:
        super().__init__(inner)
        self._recorder, self._clock = recorder, clock
        self._aim: list[float] = []

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
            self._recorder.record("/total_station/failure", event, event.timestamp)
            raise
        self._recorder.record("/total_station/shot", shot, shot.timestamp)
        return shot

    def read_inclination(self) -> TiltReading:
        reading = self.inner.read_inclination()
        self._recorder.record("/total_station/inclination", reading, reading.timestamp)
        return reading


class _RecordedBase(MobileBaseWrapper):
    def __init__(self, inner: MobileBase, recorder: Recorder, clock: Clock) -> None:
        super().__init__(inner)
        self._recorder, self._clock = recorder, clock

    def drive_to(self, goal_xy: ArrayLike, goal_yaw: float | None = None) -> DriveResult:
        result = self.inner.drive_to(goal_xy, goal_yaw)
        self._recorder.record(f"/base/{self.name}/drive", result, result.timestamp)
        return result

    def odometry(self) -> OdometryReading:
        reading = self.inner.odometry()
        self._recorder.record(f"/base/{self.name}/odometry", reading, reading.timestamp)
        return reading

    def set_pose(self, x: float, y: float, yaw: float) -> None:
        self.inner.set_pose(x, y, yaw)
        t = self._clock.now()
        fix = OdometryReading(self.name, t, float(x), float(y), float(yaw))
        self._recorder.record(f"/base/{self.name}/set_pose", fix, t)


class _RecordedLeds(MarkerLedsWrapper):
    def __init__(self, inner: MarkerLeds, recorder: Recorder) -> None:
        super().__init__(inner)
        self._recorder = recorder

    def switch(self, on: Sequence[bool]) -> LedSwitch:
        event = self.inner.switch(on)
        self._recorder.record(f"/leds/{self.child}", event, event.timestamp)
        return event


class _RecordedLedSensor(LedSensorWrapper):
    def __init__(self, inner: LedSensor, recorder: Recorder) -> None:
        super().__init__(inner)
        self._recorder = recorder

    def observe(self, child: str, sequence: SwitchingSequence) -> LedObservation:
        obs = self.inner.observe(child, sequence)
        self._recorder.record(f"/camera/{self.camera}/leds", obs, obs.timestamp)
        take = getattr(self._recorder, "image", None)
        if take is not None:
            image = self.inner.last_image()
            if image is not None:
                take(self.camera, image, obs.timestamp)
        return obs


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
    clock = ClockWrapper(rig.clock)
    return wrapped(
        rig,
        clock=lambda _: clock,
        total_station=lambda d: _RecordedTotalStation(d, recorder, clock),
        base=lambda d: _RecordedBase(d, recorder, clock),
        leds=lambda d: _RecordedLeds(d, recorder),
        led_sensor=lambda d: _RecordedLedSensor(d, recorder),
    )
