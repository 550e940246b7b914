"""check_rig holds a rig to the interface: both fidelities of the twin pass it, and a device
broken in one way fails it with that way named."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

import twin.sim  # noqa: F401  (headless rendering is configured before MuJoCo loads)
from twin.hal import LedObservation, Rig
from twin.hal.conformance import check_rig
from twin.hal.readings import TotalStationMeasurement
from twin.hal.structure import RigCheckError, check_rig_structure
from twin.hal.wrappers import (
    ClockWrapper,
    LedSensorWrapper,
    MobileBaseWrapper,
    TotalStationWrapper,
    wrapped,
)
from twin.scenario import load_scenario
from twin.sim.rig import build_sim_rig
from twin.sim.world import build_world

SMOKE = Path(__file__).resolve().parents[3] / "scenarios" / "smoke.toml"


def _sim(fidelity: str):
    return build_sim_rig(build_world(load_scenario(SMOKE)), fidelity)


def _true_prisms_level(sim) -> np.ndarray:
    """Every child's prisms in the instrument's frame (level to 1e-4 rad on the smoke
    room's floor: 0.2 mm at these distances), m."""
    position, rotation = sim.world.instrument_pose(sim.rig.parent.name)
    cubes = np.vstack([sim.world.marker_points(c)[0] for c in sim.rig.children])
    return (cubes - position) @ rotation


@pytest.mark.parametrize("fidelity", ["geometric", "render"])
def test_both_fidelities_keep_the_interface(fidelity):
    sim = _sim(fidelity)
    try:
        report = check_rig(sim.rig, prisms_level=_true_prisms_level(sim), cameras=["cam1"])
    finally:
        sim.close()
    # Every prism in sight of the parent at the start was locked and measured; every base
    # drove twice; each child was observed by the camera.
    assert report.shots == 6
    assert report.drives == 6
    assert report.observations == 2
    assert report.leds_found > 0
    assert report.images == (1 if fidelity == "render" else 0)


def test_without_known_prisms_the_shots_at_the_children_are_checked_too():
    sim = _sim("geometric")
    try:
        report = check_rig(sim.rig, observe=False)
    finally:
        sim.close()
    assert report.shots + report.documented_errors >= 2


def _broken(fidelity: str = "geometric", **wrappers) -> tuple[Rig, object]:
    sim = _sim(fidelity)
    return wrapped(sim.rig, **wrappers), sim


def _fails(rig: Rig, sim, match: str, **kwargs) -> None:
    try:
        with pytest.raises(RigCheckError, match=match):
            check_rig(rig, observe=kwargs.pop("observe", False), **kwargs)
    finally:
        sim.simulator and sim.simulator.close()
        sim.rig.close()


class MutableOdometry(MobileBaseWrapper):
    def odometry(self):
        reading = self.inner.odometry()
        fields = {f.name: getattr(reading, f.name) for f in dataclasses.fields(reading)}
        return dataclasses.make_dataclass("Odometry", list(fields))(**fields)


def test_a_reading_that_is_not_the_documented_frozen_record_is_named():
    rig, sim = _broken(base=MutableOdometry)
    _fails(rig, sim, r"MobileBase 'parent'\.odometry: expected a OdometryReading, got Odometry")


class MillimetreStation(TotalStationWrapper):
    def measure(self):
        shot = self.inner.measure()
        return dataclasses.replace(shot, distance=1e3 * shot.distance)


def test_a_shot_in_millimetres_is_refused():
    rig, sim = _broken(total_station=MillimetreStation)
    prisms = _true_prisms_level(sim)
    _fails(rig, sim, r"shot at prism 0: .*is it in metres", prisms_level=prisms)


class DegreeStation(TotalStationWrapper):
    def measure(self):
        shot = self.inner.measure()
        # Angles in degrees where they still pass the record's own range checks.
        return TotalStationMeasurement(
            shot.timestamp, shot.distance, math.degrees(shot.horizontal) % 6.28, shot.zenith
        )


def test_a_shot_with_its_angle_in_degrees_misses_the_known_prism():
    rig, sim = _broken(total_station=DegreeStation)
    _fails(
        rig, sim, r"lands .* m from the nearest known prism", prisms_level=_true_prisms_level(sim)
    )


class BackwardsClock(ClockWrapper):
    calls = 0

    def now(self):
        BackwardsClock.calls += 1
        return self.inner.now() - (5.0 if BackwardsClock.calls == 7 else 0.0)


def test_a_clock_that_goes_back_is_named():
    rig, sim = _broken(clock=BackwardsClock)
    _fails(rig, sim, r"the clock went back from")


class FutureOdometry(MobileBaseWrapper):
    def odometry(self):
        return dataclasses.replace(
            self.inner.odometry(), timestamp=self.inner.odometry().timestamp + 10
        )


def test_a_reading_stamped_after_the_call_is_named():
    rig, sim = _broken(base=FutureOdometry)
    _fails(rig, sim, r"odometry: timestamp .* lies outside the call")


class CloseOnce(MobileBaseWrapper):
    closed = False

    def close(self):
        if CloseOnce.closed:
            raise RuntimeError("already closed")
        CloseOnce.closed = True
        self.inner.close()


def test_a_second_close_that_raises_is_named():
    sim = _sim("geometric")
    rig = Rig(
        clock=sim.rig.clock,
        total_station=sim.rig.total_station,
        parent=CloseOnce(sim.rig.parent),
        children=dict(sim.rig.children),
        leds=dict(sim.rig.leds),
        led_sensors=dict(sim.rig.led_sensors),
    )
    with pytest.raises(
        RigCheckError, match=r"Rig\.close: the second close\(\) raised RuntimeError"
    ):
        check_rig(rig, observe=False)


class KeyErrorSensor(LedSensorWrapper):
    def observe(self, child, sequence):
        raise KeyError(child)


def test_an_undocumented_error_is_named_with_what_is_allowed():
    rig, sim = _broken(led_sensor=KeyErrorSensor)
    _fails(
        rig,
        sim,
        r"LedSensor\.observe raised KeyError: 'child1' \(twin\.hal documents ValueError, "
        r"DeviceLostError\)",
        observe=True,
    )


class NoSigmaSensor(LedSensorWrapper):
    def observe(self, child, sequence):
        obs = self.inner.observe(child, sequence)
        return LedObservation(
            obs.camera,
            obs.child,
            obs.timestamp,
            obs.pixels,
            np.full(len(obs.pixels), np.nan),
            obs.failures,
        )


def test_a_found_led_without_its_sigma_is_named():
    rig, sim = _broken(led_sensor=NoSigmaSensor)
    _fails(rig, sim, r"LED \d was found: its pixel and sigma_px must be finite", observe=True)


class MillimetrePixels(LedSensorWrapper):
    def observe(self, child, sequence):
        obs = self.inner.observe(child, sequence)
        return LedObservation(
            obs.camera, obs.child, obs.timestamp, 100.0 * obs.pixels, obs.sigma_px, obs.failures
        )


def test_an_led_outside_the_image_is_named():
    rig, sim = _broken(led_sensor=MillimetrePixels)
    _fails(rig, sim, r"LED \d at \(.*\) px lies outside the image", observe=True)


class HeadingAlways(MobileBaseWrapper):
    def drive_to(self, goal_xy, goal_yaw=None):
        result = self.inner.drive_to(goal_xy, goal_yaw)
        return dataclasses.replace(result, goal=np.array([*result.goal[:2], 0.0]))


def test_a_drive_without_a_heading_reports_none():
    rig, sim = _broken(base=HeadingAlways)
    _fails(rig, sim, r"a drive asked without a heading has goal yaw NaN, got 0\.0")


def test_a_rig_without_what_the_campaign_needs_is_refused():
    sim = _sim("geometric")
    try:
        rig = sim.rig
        bare = Rig(
            clock=rig.clock,
            total_station=rig.total_station,
            parent=rig.parent,
            children=dict(rig.children),
            leds=dict(rig.leds),
            led_sensors={},
        )
        with pytest.raises(RigCheckError, match="there is no LED sensor"):
            check_rig_structure(bare)
        with pytest.raises(RigCheckError, match=r"no LED sensor for the cameras \['cam9'\]"):
            check_rig_structure(rig, cameras=["cam1", "cam9"])
        swapped = Rig(
            clock=rig.clock,
            total_station=rig.total_station,
            parent=rig.parent,
            children=dict(rig.children),
            leds={"child1": rig.leds["child2"], "child2": rig.leds["child1"]},
            led_sensors=dict(rig.led_sensors),
        )
        with pytest.raises(RigCheckError, match=r"leds\['child1'\] belong to 'child2'"):
            check_rig_structure(swapped)
        with pytest.raises(ValueError, match="at least two children"):
            Rig(
                clock=rig.clock,
                total_station=rig.total_station,
                parent=rig.parent,
                children={"child1": rig.children["child1"]},
                leds=dict(rig.leds),
                led_sensors=dict(rig.led_sensors),
            )
    finally:
        sim.close()
