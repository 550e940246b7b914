"""The errors a real device adds to the interface: documented, so the conformance check
allows them; a camera without a frame gives an observation with no LED, not a crash."""

from __future__ import annotations

from pathlib import Path

import numpy as np

import twin.sim  # noqa: F401  (headless rendering is configured before MuJoCo loads)
from calib.detection.sequence import SwitchingSequence
from twin.hal import DOCUMENTED_ERRORS, DeviceLostError, ImageLedSensor, NoFrameError
from twin.hal.conformance import check_rig
from twin.hal.devices import Camera, MarkerLeds
from twin.hal.readings import CameraImage, LedSwitch
from twin.hal.wrappers import MobileBaseWrapper, TotalStationWrapper, wrapped
from twin.instruments.errors import InstrumentBusyError
from twin.scenario import load_scenario
from twin.sim.rig import build_sim_rig
from twin.sim.world import build_world

SMOKE = Path(__file__).resolve().parents[3] / "scenarios" / "smoke.toml"


def test_every_device_method_documents_a_lost_device():
    for method, errors in DOCUMENTED_ERRORS.items():
        if not method.startswith("Clock."):
            assert DeviceLostError in errors, method
    assert NoFrameError in DOCUMENTED_ERRORS["Camera.capture"]


class LostOdometry(MobileBaseWrapper):
    def odometry(self):
        raise DeviceLostError(self.name, "no packet for 2 s (test)")


class BusyStation(TotalStationWrapper):
    def read_inclination(self):
        raise InstrumentBusyError("busy (test)", code=1)


def test_the_conformance_check_allows_and_counts_the_documented_device_errors():
    sim = build_sim_rig(build_world(load_scenario(SMOKE)), "geometric")
    rig = wrapped(
        sim.rig,
        base=lambda b: LostOdometry(b) if b.name == "child2" else b,
        total_station=BusyStation,
    )
    try:
        report = check_rig(rig, observe=False)
    finally:
        sim.close()
    # The busy inclination reading and child2's odometry (its first and its check again).
    assert report.documented_errors >= 3


class Leds(MarkerLeds):
    def __init__(self) -> None:
        self.switched: list[tuple[bool, ...]] = []

    @property
    def child(self) -> str:
        return "child1"

    @property
    def count(self) -> int:
        return 4

    def switch(self, on):
        self.switched.append(tuple(on))
        return LedSwitch("child1", 0.0, tuple(on))

    def close(self) -> None:
        pass


class StalledCamera(Camera):
    """Delivers ``frames`` images, then none."""

    def __init__(self, frames: int) -> None:
        self.left = frames

    @property
    def name(self) -> str:
        return "cam1"

    @property
    def image_size(self) -> tuple[int, int]:
        return (32, 24)

    def capture(self) -> CameraImage:
        if self.left == 0:
            raise NoFrameError("cam1", "no frame in 5 s (test)")
        self.left -= 1
        return CameraImage("cam1", 0.0, np.zeros((24, 32), np.uint8))

    def close(self) -> None:
        pass


class Clock0:
    def now(self) -> float:
        return 1.0

    def sleep(self, seconds: float) -> None:
        pass


def test_a_camera_without_a_frame_gives_an_observation_without_leds():
    leds = Leds()
    sensor = ImageLedSensor(StalledCamera(2), {"child1": leds}, Clock0())  # type: ignore[arg-type]
    obs = sensor.observe("child1", SwitchingSequence.binary(4))
    assert obs.failures == ("no_frame",) * 4
    assert obs.frames == 2
    assert not obs.found.any()
    assert leds.switched[-1] == (False,) * 4  # the LEDs are off again
