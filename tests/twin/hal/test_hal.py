"""The hardware-abstraction interface: readings are frozen and checked, a rig closes every
device once, and a recorded rig records every reading and failure before the caller sees it."""

import dataclasses

import numpy as np
import pytest

from calib.detection import SwitchingSequence
from twin.hal import (
    Clock,
    DriveResult,
    DriveStatus,
    LedObservation,
    LedSensor,
    MarkerLeds,
    MobileBase,
    OdometryReading,
    Rig,
    TiltReading,
    TotalStation,
    TotalStationMeasurement,
    recorded,
)
from twin.hal.readings import LedSwitch
from twin.instruments.errors import NoPrismInConeError
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec


class FakeClock(Clock):
    def __init__(self):
        self.t, self.closed = 0.0, 0

    def now(self):
        return self.t

    def sleep(self, seconds):
        self.t += seconds

    def close(self):
        self.closed += 1


class FakeStation(TotalStation):
    def __init__(self, fail_first=0):
        self.fail, self.closed, self.aim = fail_first, 0, None

    spec = TotalStationSpec()
    inclinometer = InclinometerSpec()

    def point(self, target_level):
        self.aim = np.asarray(target_level)

    def measure(self):
        if self.fail:
            self.fail -= 1
            raise NoPrismInConeError("lost", closest_angle=0.2)
        return TotalStationMeasurement.from_polar([5.0, 0.1, 1.4], 1.0)

    def read_inclination(self):
        return TiltReading(1.0, 1e-5, -2e-5)

    def close(self):
        self.closed += 1


class FakeBase(MobileBase):
    def __init__(self, name):
        self._name, self.closed, self.pose = name, 0, np.zeros(3)

    @property
    def name(self):
        return self._name

    def drive_to(self, goal_xy, goal_yaw=None):
        self.pose = np.array([*goal_xy, goal_yaw or 0.0])
        return DriveResult(
            self._name, 2.0, [*goal_xy, np.nan], DriveStatus.REACHED, self.odometry(), 1.0
        )

    def odometry(self):
        return OdometryReading(self._name, 2.0, *self.pose)

    def set_pose(self, x, y, yaw):
        self.pose = np.array([x, y, yaw])

    def close(self):
        self.closed += 1


class FakeLeds(MarkerLeds):
    def __init__(self, child):
        self._child, self.closed = child, 0

    @property
    def child(self):
        return self._child

    @property
    def count(self):
        return 4

    def switch(self, on):
        return LedSwitch(self._child, 0.0, tuple(on))

    def close(self):
        self.closed += 1


class FakeSensor(LedSensor):
    closed = 0
    camera = "cam1"
    image_size = (320, 240)

    def observe(self, child, sequence):
        px = np.array([[10.0, 20.0], [11.0, 40.0], [np.nan, np.nan], [13.0, 80.0]])
        return LedObservation(
            "cam1", child, 3.0, px, [0.05, 0.05, np.nan, 0.05], (None, None, "occluded", None)
        )

    def close(self):
        self.closed += 1


class ListRecorder:
    def __init__(self):
        self.records = []

    def record(self, topic, record, timestamp):
        self.records.append((topic, record, timestamp))


def _rig(station=None):
    children = {"child1": FakeBase("child1"), "child2": FakeBase("child2")}
    return Rig(
        clock=FakeClock(),
        total_station=station or FakeStation(),
        parent=FakeBase("parent"),
        children=children,
        leds={c: FakeLeds(c) for c in children},
        led_sensors={"cam1": FakeSensor()},
    )


def test_readings_are_frozen_and_checked():
    r = OdometryReading("child1", 1.0, 2.0, 3.0, 0.5)
    with pytest.raises(dataclasses.FrozenInstanceError):
        r.x = 0.0
    with pytest.raises(ValueError, match="finite"):
        OdometryReading("child1", 1.0, np.nan, 3.0, 0.5)
    obs = FakeSensor().observe("child1", None)
    assert obs.found.tolist() == [True, True, False, True]
    assert not obs.complete
    with pytest.raises(ValueError, match="read-only"):
        obs.pixels[0, 0] = 1.0
    with pytest.raises(ValueError, match="failure"):
        LedObservation("c", "k", 0.0, [[1.0, 2.0]], [0.1], ("occluded",))
    with pytest.raises(ValueError, match="DriveStatus"):
        DriveResult("p", 0.0, [0, 0, 0], "reached", r, 1.0)


def test_rig_closes_every_device_once_and_needs_two_children():
    rig = _rig()
    with rig:
        pass
    devices = [rig.clock, rig.total_station, rig.parent, *rig.children.values()]
    devices += [*rig.leds.values(), *rig.led_sensors.values()]
    assert [d.closed for d in devices] == [1] * len(devices)
    with pytest.raises(ValueError, match="two children"):
        Rig(
            FakeClock(),
            FakeStation(),
            FakeBase("p"),
            {"c": FakeBase("c")},
            {"c": FakeLeds("c")},
            {},
        )
    with pytest.raises(ValueError, match="without LEDs"):
        Rig(
            FakeClock(),
            FakeStation(),
            FakeBase("p"),
            {"a": FakeBase("a"), "b": FakeBase("b")},
            {},
            {},
        )


def test_recorded_rig_records_readings_commands_and_failures():
    rec = ListRecorder()
    rig = recorded(_rig(FakeStation(fail_first=1)), rec)
    rig.total_station.point([1.0, 2.0, 3.0])
    with pytest.raises(NoPrismInConeError):
        rig.total_station.measure()
    shot = rig.total_station.measure()
    rig.total_station.read_inclination()
    rig.children["child1"].drive_to([1.0, 2.0], 0.5)
    rig.children["child1"].set_pose(1.0, 2.0, 0.4)
    rig.leds["child2"].switch([True, False, False, True])
    rig.led_sensors["cam1"].observe("child1", SwitchingSequence.binary(4))
    topics = [t for t, _, _ in rec.records]
    assert topics == [
        "/total_station/failure",
        "/total_station/shot",
        "/total_station/inclination",
        "/base/child1/drive",
        "/base/child1/set_pose",
        "/leds/child2",
        "/camera/cam1/leds",
    ]
    failure = rec.records[0][1]
    assert failure.kind == "no_prism_in_cone"
    assert failure.details["aim_level"] == [1.0, 2.0, 3.0]
    assert rec.records[1][1] is shot
    assert rig.base("child1").odometry().yaw == pytest.approx(0.4)
    with pytest.raises(ValueError, match="no robot"):
        rig.base("child9")
