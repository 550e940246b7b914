"""The GeoCOM driver against the emulator: shots come back where the prisms are, angles
have the right sign, return codes become the project's errors, and a line that lies,
stalls or breaks is reported as such."""

from __future__ import annotations

import math
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.twin.emulators.test_geocom_emulator import FakeStation
from twin.drivers.clock import WallClock
from twin.drivers.geocom import LOST_AFTER_TIMEOUTS, GeoComTotalStation
from twin.drivers.geocom_codes import (
    ANGLE_WARNINGS,
    DISTANCE_CODES,
    NO_TARGET_CODES,
    error_class,
    error_for_code,
    geocom_from_polar,
    inclination_from_tilt,
    polar_from_geocom,
    tilt_from_inclination,
)
from twin.emulators.geocom import GeoComEmulator
from twin.emulators.geocom_faults import Fault
from twin.emulators.links import PtyLink, TcpLink
from twin.hal.devices import DOCUMENTED_ERRORS
from twin.hal.errors import DeviceLostError
from twin.instruments.errors import (
    DistanceMeasurementError,
    InstrumentBusyError,
    InstrumentFaultError,
    InstrumentTimeoutError,
    LineOfSightBlockedError,
    NoPrismInConeError,
    OutOfRangeError,
    TiltOutOfRangeError,
)
from twin.instruments.tilt import level_points, tilt_from_orientation, tilt_rotation
from twin.instruments.total_station import InclinometerSpec

SMOKE = Path(__file__).resolve().parents[3] / "scenarios" / "smoke.toml"
TIMEOUT_S = 10.0
"""The driver's reply timeout in rig seconds: 2 s wall on the usual clock (``TIME_SCALE``),
0.2 s where a test waits for silence (``FAST``)."""
TIME_SCALE = 5.0
FAST = 50.0

MAKE_POSITIONING, FINE_ADJUST, DO_MEASURE, SIMPLE_MEA, GET_ANGLE1 = 9027, 9037, 2008, 2108, 2003


@pytest.fixture(autouse=True)
def fast_geocompy(monkeypatch: pytest.MonkeyPatch) -> None:
    """geocompy rests a second after its connection test; the emulator needs no rest."""
    import geocompy.geo

    monkeypatch.setattr(geocompy.geo, "sleep", lambda seconds: None)


@pytest.fixture
def station() -> FakeStation:
    return FakeStation()


BOTH_LINKS = pytest.mark.parametrize("emulator", ["pty", "tcp"], indirect=True)
"""Run a test over a pty and over TCP (pyserial rests 0.3 s when it closes a socket)."""


@pytest.fixture
def emulator(request: pytest.FixtureRequest, station: FakeStation) -> Iterator[GeoComEmulator]:
    """An emulator on a pty (or on TCP with ``BOTH_LINKS``) around the fake station."""
    kind = getattr(request, "param", "pty")
    link = PtyLink() if kind == "pty" else TcpLink()
    emu = GeoComEmulator(station, threading.RLock(), link=link)
    try:
        yield emu.start()
    finally:
        emu.close()


def open_driver(
    emulator: GeoComEmulator, station: FakeStation, time_scale: float = TIME_SCALE
) -> GeoComTotalStation:
    return GeoComTotalStation(
        emulator.address,
        clock=WallClock(time_scale=time_scale),
        spec=station.spec,
        inclinometer=station.inclinometer,
        timeout_s=TIMEOUT_S,
    )


@pytest.fixture
def driver(emulator: GeoComEmulator, station: FakeStation) -> Iterator[GeoComTotalStation]:
    drv = open_driver(emulator, station)
    try:
        yield drv
    finally:
        drv.close()


# -- angles, once ----------------------------------------------------------------------------


def test_a_prism_on_plus_y_is_hz_three_halves_pi() -> None:
    # GeoCOM turns clockwise: +y (the project's pi/2) is Hz = 3pi/2; +x is 0 in both.
    assert geocom_from_polar(math.pi / 2, math.pi / 2) == pytest.approx(
        (1.5 * math.pi, math.pi / 2)
    )
    assert polar_from_geocom(1.5 * math.pi, math.pi / 2) == pytest.approx(
        (math.pi / 2, math.pi / 2)
    )
    assert geocom_from_polar(0.0, 1.0) == (0.0, 1.0)
    assert polar_from_geocom(0.25 * math.pi, 1.0) == pytest.approx((1.75 * math.pi, 1.0))
    # face II: the same direction over the zenith
    assert polar_from_geocom(0.5 * math.pi, 2 * math.pi - 1.0) == pytest.approx(
        (0.5 * math.pi, 1.0)
    )
    with pytest.raises(ValueError, match="zenith"):
        geocom_from_polar(0.0, 4.0)
    with pytest.raises(ValueError, match="hz"):
        polar_from_geocom(math.nan, 1.0)


def test_the_driver_turns_to_plus_y_and_reads_it_back(
    driver: GeoComTotalStation, station: FakeStation
) -> None:
    driver.point([0.0, 2.0, 0.0])
    assert station.aim is not None
    # geocompy writes request angles with 6 decimals (0.2")
    np.testing.assert_allclose(station.aim / np.linalg.norm(station.aim), [0, 1, 0], atol=1e-6)
    shot = driver.measure()
    assert shot.horizontal == pytest.approx(math.pi / 2, abs=1e-12)
    np.testing.assert_allclose(shot.to_cartesian(), [0.0, 5.0, 0.0], atol=1e-9)


_ANGLE = st.floats(0.0, 2 * math.pi, exclude_max=True)
_ZENITH = st.floats(0.0, math.pi)


@settings(deadline=None)
@given(horizontal=_ANGLE, zenith=_ZENITH)
def test_angle_conversions_round_trip(horizontal: float, zenith: float) -> None:
    hz, v = geocom_from_polar(horizontal, zenith)
    assert 0.0 <= hz < 2 * math.pi
    assert v == zenith
    assert math.cos(hz) == pytest.approx(math.cos(horizontal), abs=1e-12)
    assert math.sin(hz) == pytest.approx(-math.sin(horizontal), abs=1e-12)  # clockwise
    back, zen = polar_from_geocom(hz, v)
    assert 0.0 <= back < 2 * math.pi
    assert zen == pytest.approx(zenith)
    assert math.cos(back - horizontal) == pytest.approx(1.0, abs=1e-12)
    face2 = (
        polar_from_geocom(hz + math.pi, 2 * math.pi - v)
        if 1e-9 < v < math.pi - 1e-9
        else (back, zen)
    )
    assert math.cos(face2[0] - horizontal) == pytest.approx(1.0, abs=1e-9)
    assert face2[1] == pytest.approx(zenith, abs=1e-12)


_TILT = st.floats(-0.01, 0.01)


@settings(deadline=None)
@given(roll=_TILT, pitch=_TILT, hz=_ANGLE)
def test_inclination_matches_the_tilt_rotation(roll: float, pitch: float, hz: float) -> None:
    cross, length = inclination_from_tilt(roll, pitch, hz)
    # the line of sight and the trunnion axis's left end, level in the instrument frame
    a = -hz
    r = tilt_rotation(roll, pitch)
    sight = r @ [math.cos(a), math.sin(a), 0.0]
    left = r @ [-math.sin(a), math.cos(a), 0.0]
    assert length == pytest.approx(math.asin(sight[2]), abs=1e-15)
    assert cross == pytest.approx(math.asin(left[2]), abs=1e-15)
    assert tilt_from_inclination(cross, length, hz) == pytest.approx((roll, pitch), abs=1e-15)


def test_inclination_along_x_is_roll_and_minus_pitch() -> None:
    assert inclination_from_tilt(1e-3, 2e-3, 0.0) == pytest.approx((1e-3, -2e-3), rel=1e-5)
    # telescope along +y (Hz = 3pi/2): the line of sight rises with roll
    assert inclination_from_tilt(1e-3, 2e-3, 1.5 * math.pi) == pytest.approx((2e-3, 1e-3), rel=1e-5)


# -- shots -----------------------------------------------------------------------------------


def test_identify(driver: GeoComTotalStation) -> None:
    assert driver.identify() == {
        "name": "TS16 R500",
        "serial": "1234567",
        "firmware": "1.0.0",
        "geocom": "1.50.0",
    }


@BOTH_LINKS
def test_every_prism_comes_back(driver: GeoComTotalStation, station: FakeStation) -> None:
    assert driver.spec is station.spec
    assert driver.inclinometer is station.inclinometer
    for prism in station.prisms:
        driver.point(prism * 0.8 + [0.05, -0.05, 0.02])  # a guess near the prism
        shot = driver.measure()
        np.testing.assert_allclose(shot.to_cartesian(), prism, atol=1e-9)
        assert shot.tilt is not None
        assert shot.tilt.roll == pytest.approx(0.0, abs=1e-15)


def test_tilt_comes_back_at_any_pointing(driver: GeoComTotalStation, station: FakeStation) -> None:
    station.tilt = (3e-4, -2e-4)
    for target in ([1.0, 1.0, 0.0], [-2.0, 0.5, 1.0], [0.3, -4.0, -0.2]):
        driver.point(target)
        reading = driver.read_inclination()
        assert (reading.roll, reading.pitch) == pytest.approx(station.tilt, abs=1e-12)


def test_a_reading_beyond_the_working_range_is_refused(station: FakeStation) -> None:
    station.tilt = (2.0 * InclinometerSpec().working_range, 0.0)
    emu = GeoComEmulator(station, threading.RLock()).start()
    try:
        drv = open_driver(emu, station)
        try:
            drv.point([4.0, 0.0, 1.0])
            with pytest.raises(TiltOutOfRangeError, match="compensator"):
                drv.read_inclination()
            with pytest.raises(TiltOutOfRangeError):
                drv.measure()  # the shot's inclination reading is refused too
        finally:
            drv.close()
    finally:
        emu.close()


@pytest.mark.parametrize("target", [[0, 0, 0], [1.0, math.nan, 0.0], [1.0, 2.0]])
def test_a_bad_aim_is_a_value_error(driver: GeoComTotalStation, target: list) -> None:
    with pytest.raises(ValueError, match="finite non-zero"):
        driver.point(target)


def test_the_twin_shoots_through_geocom() -> None:
    from twin.scenario import load_scenario
    from twin.sim.rig import build_sim_rig
    from twin.sim.world import build_world

    sim = build_sim_rig(build_world(load_scenario(SMOKE)), "geometric", seed=3)
    station = sim.rig.total_station
    world = station.world
    position, rotation = world.instrument_pose(station.parent)
    roll, pitch = tilt_from_orientation(rotation)
    cubes = np.vstack([world.marker_points(c)[0] for c in station.children])
    truth = level_points((cubes - position) @ rotation, roll, pitch)
    emu = GeoComEmulator(station, threading.RLock()).start()
    try:
        drv = GeoComTotalStation(
            emu.address,
            clock=WallClock(),
            spec=station.spec,
            inclinometer=station.inclinometer,
            timeout_s=2.0,
        )
        try:
            hits = 0
            for cube in truth:
                drv.point(cube)
                try:
                    shot = drv.measure()
                except (NoPrismInConeError, LineOfSightBlockedError):
                    continue  # a cube hidden from the instrument
                hits += 1
                nearest = np.min(np.linalg.norm(truth - shot.to_cartesian(), axis=1))
                assert nearest < 5e-3  # 2 mm + 2 ppm, 5" at about 2.5 m
                assert shot.tilt is not None
        finally:
            drv.close()
    finally:
        emu.close()
    assert hits >= 3


# -- return codes ----------------------------------------------------------------------------

CASES = [
    (8710, FINE_ADJUST, NoPrismInConeError, "AUT_NO_TARGET"),
    (8711, FINE_ADJUST, NoPrismInConeError, "AUT_MULTIPLE_TARGETS"),
    (1292, SIMPLE_MEA, DistanceMeasurementError, "TMC_DIST_ERROR"),
    (1294, SIMPLE_MEA, DistanceMeasurementError, "TMC_SIGNAL_ERROR"),
    (818, SIMPLE_MEA, OutOfRangeError, "EDM_DISTRANGE_ERR"),
    (1293, SIMPLE_MEA, InstrumentBusyError, "TMC_BUSY"),
    (13, DO_MEASURE, InstrumentBusyError, "SYSBUSY"),
    (8704, MAKE_POSITIONING, InstrumentTimeoutError, "AUT_TIMEOUT"),
    (22, GET_ANGLE1, TiltOutOfRangeError, "INSTRUMENT_TILT"),
    (4, FINE_ADJUST, InstrumentFaultError, "FATAL"),
    (54321, SIMPLE_MEA, InstrumentFaultError, "unknown code"),
]


@pytest.mark.parametrize(("code", "rpc", "error", "name"), CASES)
def test_return_codes_become_typed_errors(
    driver: GeoComTotalStation,
    emulator: GeoComEmulator,
    code: int,
    rpc: int,
    error: type[Exception],
    name: str,
) -> None:
    emulator.faults.set(Fault.CODE, code=code, rpc=rpc, times=1)
    with pytest.raises(error) as caught:  # noqa: PT012  (a positioning or the shot)
        driver.point([4.0, 0.0, 1.0])
        driver.measure()
    assert caught.type is error
    assert f"{code} ({name})" in str(caught.value)
    assert caught.value.details["code"] == code
    driver.point([4.0, 0.0, 1.0])
    driver.measure()  # the instrument is still there


@pytest.mark.parametrize(
    ("code", "rpc", "method", "kind"),
    [
        (8710, MAKE_POSITIONING, "point", NoPrismInConeError),  # AUT_NO_TARGET
        (22, MAKE_POSITIONING, "point", TiltOutOfRangeError),  # INSTRUMENT_TILT
        (1292, GET_ANGLE1, "read_inclination", DistanceMeasurementError),  # TMC_DIST_ERROR
        (818, GET_ANGLE1, "read_inclination", OutOfRangeError),  # EDM_DISTRANGE_ERR
    ],
)
def test_a_code_a_method_does_not_document_is_a_fault(
    driver: GeoComTotalStation,
    emulator: GeoComEmulator,
    code: int,
    rpc: int,
    method: str,
    kind: type[Exception],
) -> None:
    assert kind not in DOCUMENTED_ERRORS[f"TotalStation.{method}"]
    emulator.faults.set(Fault.CODE, code=code, rpc=rpc, times=1)
    call = getattr(driver, method)
    with pytest.raises(InstrumentFaultError) as caught:
        call([4.0, 0.0, 1.0]) if method == "point" else call()
    assert caught.type is InstrumentFaultError
    assert f"GeoCOM return code {code} (" in str(caught.value)
    assert caught.value.details["code"] == code
    call([4.0, 0.0, 1.0]) if method == "point" else call()  # the instrument is still there


def test_errors_of_the_twin_travel_as_codes(
    driver: GeoComTotalStation, station: FakeStation
) -> None:
    driver.point([0.0, -1.0, -5.0])  # nothing there
    with pytest.raises(NoPrismInConeError, match="8710"):
        driver.measure()
    for raised, expected in (
        (LineOfSightBlockedError("blocked"), NoPrismInConeError),
        (OutOfRangeError("far"), OutOfRangeError),
        (DistanceMeasurementError("no signal"), DistanceMeasurementError),
        (InstrumentBusyError("busy"), InstrumentBusyError),
        (RuntimeError("surprise"), InstrumentFaultError),
    ):
        station.measure_error = raised
        with pytest.raises(expected):
            driver.measure()
    station.measure_error = None
    driver.point([4.0, 0.0, 1.0])
    assert driver.measure().distance == pytest.approx(math.sqrt(17.0))


def test_warnings_with_values_are_shots(
    driver: GeoComTotalStation, emulator: GeoComEmulator
) -> None:
    emulator.faults.set(Fault.WARNING, code=1283, rpc=SIMPLE_MEA, times=1)  # no full correction
    driver.point([4.0, 0.0, 1.0])
    assert driver.measure().distance == pytest.approx(math.sqrt(17.0))
    emulator.faults.set(Fault.WARNING, code=1285, rpc=SIMPLE_MEA, times=1)  # angles only
    with pytest.raises(DistanceMeasurementError, match="1285"):
        driver.measure()


def test_the_code_table() -> None:
    assert error_class(1283) is InstrumentFaultError  # a warning, never a distance error
    assert 1283 not in DISTANCE_CODES
    assert 1283 in ANGLE_WARNINGS
    assert all(error_class(c) is NoPrismInConeError for c in NO_TARGET_CODES)
    err = error_for_code(99999, "TMC_GetSimpleMea")
    assert isinstance(err, InstrumentFaultError)
    assert "99999 (unknown code)" in str(err)
    assert err.details["code"] == 99999


# -- a line that lies, stalls or breaks --------------------------------------------------------


def test_garbage_is_retried_once_where_safe(
    driver: GeoComTotalStation, emulator: GeoComEmulator
) -> None:
    driver.point([4.0, 0.0, 1.0])
    emulator.faults.set(Fault.GARBAGE, rpc=SIMPLE_MEA, times=1)
    before = emulator.requests
    assert driver.measure().distance == pytest.approx(math.sqrt(17.0))
    assert emulator.requests - before == 5  # fine adjust, measure, 2 x simple, angle
    assert driver.rejected["undecodable"] == 1
    emulator.faults.set(Fault.GARBAGE, rpc=SIMPLE_MEA, times=2)
    with pytest.raises(InstrumentFaultError, match="3074") as caught:
        driver.measure()
    assert caught.value.details["code"] == 3074
    emulator.faults.set(Fault.GARBAGE, rpc=MAKE_POSITIONING, times=1)
    with pytest.raises(InstrumentFaultError, match="AUT_MakePositioning"):
        driver.point([4.0, 0.0, 1.0])  # a motion is not sent twice
    driver.point([4.0, 0.0, 1.0])
    assert driver.measure().distance == pytest.approx(math.sqrt(17.0))


def test_a_truncated_reply(driver: GeoComTotalStation, emulator: GeoComEmulator) -> None:
    emulator.faults.set(Fault.TRUNCATED, rpc=GET_ANGLE1, times=1)
    driver.read_inclination()  # read again
    emulator.faults.set(Fault.TRUNCATED, rpc=FINE_ADJUST, times=1)
    with pytest.raises(InstrumentFaultError, match="could not be decoded"):
        driver.measure()
    driver.point([4.0, 0.0, 1.0])
    assert driver.measure().distance == pytest.approx(math.sqrt(17.0))


@BOTH_LINKS
def test_a_device_that_stops_answering(emulator: GeoComEmulator, station: FakeStation) -> None:
    driver = open_driver(emulator, station, time_scale=FAST)
    try:
        emulator.faults.set(Fault.SILENT, times=1)
        with pytest.raises(InstrumentTimeoutError, match="no reply") as caught:
            driver.read_inclination()
        assert caught.value.details["timeout_s"] == TIMEOUT_S
        driver.read_inclination()  # it answers again: the count starts over
        emulator.faults.set(Fault.SILENT)
        for _ in range(LOST_AFTER_TIMEOUTS - 1):
            with pytest.raises(InstrumentTimeoutError):
                driver.read_inclination()
        with pytest.raises(DeviceLostError, match="3 requests in a row") as lost:
            driver.read_inclination()
        assert lost.value.device == "total_station"
        emulator.faults.clear()
        with pytest.raises(DeviceLostError):
            driver.measure()  # lost stays lost
    finally:
        driver.close()


@BOTH_LINKS
def test_a_link_dropped_mid_run(driver: GeoComTotalStation, emulator: GeoComEmulator) -> None:
    driver.point([4.0, 0.0, 1.0])
    emulator.faults.set(Fault.DROP, rpc=SIMPLE_MEA)
    with pytest.raises(DeviceLostError, match="failed") as lost:
        driver.measure()
    assert lost.value.details["port"] == emulator.address
    # The message names the device and its link.
    named = f"total_station on {emulator.address} (GeoCOM): connection lost: the link failed"
    assert str(lost.value).startswith(named)
    assert lost.value.link == f"{emulator.address} (GeoCOM)"
    with pytest.raises(DeviceLostError):
        driver.read_inclination()


def test_nobody_on_the_line(station: FakeStation) -> None:
    with PtyLink() as link, pytest.raises(DeviceLostError, match="no GeoCOM instrument"):
        GeoComTotalStation(
            link.address,
            clock=WallClock(time_scale=FAST),
            spec=station.spec,
            inclinometer=None,
            timeout_s=TIMEOUT_S,
        )
    with pytest.raises(DeviceLostError, match="cannot open"):
        GeoComTotalStation(
            "/dev/does-not-exist", clock=WallClock(), spec=station.spec, inclinometer=None
        )
    with pytest.raises(ValueError, match="timeout_s"):
        GeoComTotalStation(
            "loop://", clock=WallClock(), spec=station.spec, inclinometer=None, timeout_s=0.0
        )


def test_close_twice(emulator: GeoComEmulator, station: FakeStation) -> None:
    drv = open_driver(emulator, station)
    drv.close()
    drv.close()
    with pytest.raises(DeviceLostError, match="closed"):
        drv.measure()
