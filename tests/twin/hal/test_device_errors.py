"""The errors a real device adds to the interface: documented, so the conformance check
allows them; a camera without a frame gives an observation with no LED, not a crash."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

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


def _detections(failures):
    """What the detector returns for LEDs that failed as ``failures`` (None: found)."""
    from types import SimpleNamespace

    from calib.detection import DetectionFailure

    return SimpleNamespace(
        leds=[
            SimpleNamespace(
                led=k,
                pixel=None if f else (10.0 + k, 12.0),
                sigma_px=0.05,
                failure=DetectionFailure(f) if f else None,
            )
            for k, f in enumerate(failures)
        ]
    )


def test_a_sequence_whose_scene_changed_is_captured_again(monkeypatch):
    import twin.hal.led_sensing as sensing

    # Something moved under LED 1 in the first capture (a frame from before the switch, a
    # person walking past); the second capture finds every LED.
    answers = [
        _detections([None, "scene_changed", None, None]),
        _detections([None, None, None, None]),
    ]
    monkeypatch.setattr(sensing, "detect_leds", lambda *a, **k: answers.pop(0))
    sequence = SwitchingSequence.binary(4)
    sensor = ImageLedSensor(StalledCamera(100), {"child1": Leds()}, Clock0())  # type: ignore[arg-type]
    obs = sensor.observe("child1", sequence)
    assert obs.failures == (None,) * 4
    assert obs.frames == 2 * len(sequence.pattern)
    assert not answers


def test_a_scene_that_keeps_changing_keeps_the_best_capture(monkeypatch):
    import twin.hal.led_sensing as sensing

    answers = [
        _detections([None, "scene_changed", "scene_changed", None]),
        _detections([None, "scene_changed", None, None]),
        _detections(["scene_changed", "scene_changed", "scene_changed", None]),
        _detections([None, None, None, None]),  # never asked for: the retries are spent
    ]
    calls = []

    def detect(*args, **kwargs):
        calls.append(1)
        return answers.pop(0)

    monkeypatch.setattr(sensing, "detect_leds", detect)
    sequence = SwitchingSequence.binary(4)
    sensor = ImageLedSensor(StalledCamera(100), {"child1": Leds()}, Clock0())  # type: ignore[arg-type]
    obs = sensor.observe("child1", sequence)
    assert len(calls) == 1 + sensing.SCENE_RETRIES
    assert obs.failures == (None, "scene_changed", None, None)
    assert obs.frames == len(calls) * len(sequence.pattern)
    # Without retries the first capture is the observation.
    answers[:] = [_detections([None, "scene_changed", None, None])]
    once = ImageLedSensor(
        StalledCamera(100),
        {"child1": Leds()},
        Clock0(),  # type: ignore[arg-type]
        scene_retries=0,
    )
    assert once.observe("child1", sequence).failures == (None, "scene_changed", None, None)
    with pytest.raises(ValueError, match="scene_retries"):
        ImageLedSensor(StalledCamera(1), {}, Clock0(), scene_retries=-1)  # type: ignore[arg-type]
