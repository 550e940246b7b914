"""The GeoCOM emulator answers requests written from Leica's reference manual, and geocompy's
own client, as the instrument does; framing survives any bytes; faults misbehave on cue."""

from __future__ import annotations

import math
import threading
from collections.abc import Iterator

import geocompy.geo
import numpy as np
import pytest
import serial
from geocompy.communication import SerialConnection, crc16_bytewise
from geocompy.geo import GeoCom
from geocompy.geo.gctypes import GeoComCode
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import ArrayLike

from twin.emulators.geocom import GeoComEmulator
from twin.emulators.geocom_faults import GARBAGE, Fault, GeoComFaults
from twin.emulators.geocom_requests import Request, RequestError, format_reply, parse_request
from twin.emulators.links import Link, PtyLink, TcpLink
from twin.hal.devices import TotalStation
from twin.hal.readings import TiltReading, TotalStationMeasurement
from twin.instruments.errors import NoPrismInConeError
from twin.instruments.polar import cartesian2polar
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec

PRISMS = np.array([[0.0, 5.0, 0.0], [4.0, 0.0, 1.0], [-3.0, -3.0, -0.5]])
"""Prisms of the fake station, levelled frame, m: on +y, near +x, behind on the left."""


class FakeStation(TotalStation):
    """A noiseless instrument with known prisms in its levelled frame.

    The automatic aim locks the prism nearest the pointing direction within the spec's
    cone; ``measure_error``/``tilt_error`` make the next calls fail; ``tilt`` is the
    inclination it reads.
    """

    def __init__(
        self,
        prisms: ArrayLike = PRISMS,
        *,
        tilt: tuple[float, float] = (0.0, 0.0),
        inclinometer: InclinometerSpec | None = None,
    ) -> None:
        self.prisms = np.asarray(prisms, dtype=float).reshape(-1, 3)
        self.tilt = tilt
        self._spec = TotalStationSpec.noiseless()
        self._inclinometer = inclinometer or InclinometerSpec()
        self.aim: np.ndarray | None = None
        self.measure_error: Exception | None = None
        self.tilt_error: Exception | None = None
        self.measured = 0

    @property
    def spec(self) -> TotalStationSpec:
        return self._spec

    @property
    def inclinometer(self) -> InclinometerSpec | None:
        return self._inclinometer

    def point(self, target_level: ArrayLike) -> None:
        aim = np.asarray(target_level, dtype=float).reshape(3)
        if not np.all(np.isfinite(aim)) or not np.any(aim):
            raise ValueError(f"bad aim {aim}")
        self.aim = aim

    def measure(self) -> TotalStationMeasurement:
        self.measured += 1
        if self.measure_error is not None:
            raise self.measure_error
        assert self.aim is not None
        u = self.aim / np.linalg.norm(self.aim)
        d = self.prisms / np.linalg.norm(self.prisms, axis=1, keepdims=True)
        angles = np.arccos(np.clip(d @ u, -1.0, 1.0))
        k = int(np.argmin(angles))
        if angles[k] > self._spec.aim_cone:
            raise NoPrismInConeError("no prism near the aim")
        return TotalStationMeasurement.from_polar(cartesian2polar(self.prisms[k]), 0.0)

    def read_inclination(self) -> TiltReading:
        if self.tilt_error is not None:
            raise self.tilt_error
        return TiltReading(timestamp=1.5, roll=self.tilt[0], pitch=self.tilt[1])

    def close(self) -> None:
        """Nothing to release."""


@pytest.fixture
def fast_geocompy(monkeypatch: pytest.MonkeyPatch) -> None:
    """geocompy waits a second after its connection test; the emulator needs no rest."""
    monkeypatch.setattr(geocompy.geo, "sleep", lambda seconds: None)


@pytest.fixture
def station() -> FakeStation:
    return FakeStation()


@pytest.fixture
def emulator(station: FakeStation) -> Iterator[GeoComEmulator]:
    emu = GeoComEmulator(station, threading.RLock())
    try:
        yield emu.start()
    finally:
        emu.close()


@pytest.fixture
def line(emulator: GeoComEmulator) -> Iterator[serial.SerialBase]:
    """The driver's end of the emulator's pty, raw."""
    port = serial.serial_for_url(emulator.address, timeout=1.0)
    try:
        yield port
    finally:
        port.close()


def ask(port: serial.SerialBase, request: bytes) -> bytes:
    port.write(request)
    return port.read_until(b"\r\n")


def values(reply: bytes) -> list[float]:
    return [float(v) for v in reply.decode().strip().split(":")[1].split(",")[1:]]


# -- raw requests from the reference manual --------------------------------------------------


def test_raw_requests_from_the_manual(line: serial.SerialBase) -> None:
    assert ask(line, b"%R1Q,0:\r\n") == b"%R1P,0,0:0\r\n"  # COM_NullProc
    assert ask(line, b"%R1Q,5004:\r\n") == b'%R1P,0,0:0,"TS16 R500"\r\n'  # instrument name
    assert ask(line, b"%R1Q,5003,17:\r\n") == b"%R1P,0,17:0,1234567\r\n"  # serial, TrId 17
    assert ask(line, b"%R1Q,108:\r\n") == b"%R1P,0,0:0,15\r\n"  # double precision
    # a bare LF clears the line and is not answered
    assert ask(line, b"\n%R1Q,110:\r\n") == b"%R1P,0,0:0,1,50,0\r\n"


def test_raw_shot_at_a_prism_on_plus_y(line: serial.SerialBase, station: FakeStation) -> None:
    # AUT_MakePositioning(Hz, V, PosMode, ATRMode, bDummy): Hz = 3pi/2 clockwise is +y.
    assert ask(line, b"%R1Q,9027:4.71238898038469,1.5707963267949,0,0,0\r\n") == (b"%R1P,0,0:0\r\n")
    assert station.aim is not None
    np.testing.assert_allclose(station.aim / np.linalg.norm(station.aim), [0, 1, 0], atol=1e-12)
    # TMC_GetSimpleMea before any measurement: no distance (TMC_DIST_ERROR)
    assert ask(line, b"%R1Q,2108:5000,1\r\n") == b"%R1P,0,0:1292\r\n"
    assert ask(line, b"%R1Q,9037:0.1,0.1,0\r\n") == b"%R1P,0,0:0\r\n"  # AUT_FineAdjust
    assert ask(line, b"%R1Q,2108,3:5000,1\r\n") == b"%R1P,0,3:1292\r\n"  # no TMC_DoMeasure
    assert ask(line, b"%R1Q,2008:1,1\r\n") == b"%R1P,0,0:0\r\n"  # TMC_DoMeasure(DEF_DIST)
    reply = ask(line, b"%R1Q,2108,4:5000,1\r\n")
    assert reply.startswith(b"%R1P,0,4:0,")
    np.testing.assert_allclose(values(reply), [1.5 * math.pi, 0.5 * math.pi, 5.0], atol=1e-12)
    # BAP_MeasDistanceAngle(DistMode) -> Hz, V, distance, DistMode
    reply = ask(line, b"%R1Q,17017:1\r\n")
    np.testing.assert_allclose(values(reply), [1.5 * math.pi, 0.5 * math.pi, 5.0, 1], atol=1e-12)
    # TMC_DoMeasure(TMC_CLEAR) forgets the distance
    assert ask(line, b"%R1Q,2008:3,1\r\n") == b"%R1P,0,0:0\r\n"
    assert ask(line, b"%R1Q,2108:5000,1\r\n") == b"%R1P,0,0:1292\r\n"


def test_raw_no_target_and_inclination(line: serial.SerialBase, station: FakeStation) -> None:
    # straight down: no prism in the cone -> AUT_NO_TARGET
    assert ask(line, b"%R1Q,9027:0.0,3.0,0,0,0\r\n") == b"%R1P,0,0:0\r\n"
    assert ask(line, b"%R1Q,9037:0.1,0.1,0\r\n") == b"%R1P,0,0:8710\r\n"
    # TMC_GetAngle1(Mode): Hz, V, accuracy, time, cross, length, accuracy, time, face
    station.tilt = (2e-4, -1e-4)
    fields = ask(line, b"%R1Q,2003:0\r\n").decode().strip().split(":")[1].split(",")
    assert fields[0] == "0"
    assert len(fields) == 10
    assert float(fields[5]) == pytest.approx(2e-4)  # Hz = 0: cross = roll
    assert float(fields[6]) == pytest.approx(1e-4)  # Hz = 0: length = -pitch
    assert fields[4] == fields[8] == "1500"  # ms
    from twin.instruments.errors import TiltOutOfRangeError

    station.tilt_error = TiltOutOfRangeError("tilted")
    assert ask(line, b"%R1Q,2003:0\r\n") == b"%R1P,0,0:22\r\n"  # INSTRUMENT_TILT
    assert ask(line, b"%R1Q,2107:1\r\n") == b"%R1P,0,0:22\r\n"


def test_raw_errors_never_crash(line: serial.SerialBase, emulator: GeoComEmulator) -> None:
    assert ask(line, b"%R1Q,4321:\r\n") == b"%R1P,3081,0:0\r\n"  # COM_PROC_UNAVAIL
    assert ask(line, b"%R1Q,4321,9:1,2\r\n") == b"%R1P,3081,9:0\r\n"
    assert ask(line, b"hello\r\n") == b"%R1P,3080,0:0\r\n"  # COM_CANT_DECODE_REQ
    assert ask(line, b"\xff\xfe%R1Q,0:\r\n") == b"%R1P,3080,0:0\r\n"
    assert ask(line, b"%R1Q,9027:abc,1.0,0,0,0\r\n") == b"%R1P,0,0:2\r\n"  # IVPARAM
    assert ask(line, b"%R1Q,9027:\r\n") == b"%R1P,0,0:2\r\n"
    assert ask(line, b"%R1Q,9027:nan,1.0,0,0,0\r\n") == b"%R1P,0,0:2\r\n"
    assert ask(line, b"%R1Q,0:\r\n") == b"%R1P,0,0:0\r\n"  # still serving


def test_checksums(line: serial.SerialBase) -> None:
    body = "%R1Q,5003,2:"
    crc = crc16_bytewise(body)
    reply = ask(line, f"%R1Q,5003,2,{crc}:\r\n".encode())
    m = GeoCom._R1P.match(reply.decode().strip())
    assert m is not None
    assert m[5] == "1234567"
    unsigned = reply.decode().strip().replace(f",{m[3]}:", ":")
    assert int(m[3]) == crc16_bytewise(unsigned)
    assert ask(line, f"%R1Q,5003,2,{crc ^ 1}:\r\n".encode()) == b"%R1P,3101,2:0\r\n"


# -- framing, for any input -------------------------------------------------------------------

_FLOATS = st.floats(allow_nan=False, allow_infinity=False, width=64)
_PARAMS = st.lists(
    st.one_of(
        st.integers(-(2**31), 2**31 - 1).map(str),
        _FLOATS.map(lambda x: f"{x:f}"),
        st.text(st.characters(codec="ascii", exclude_characters='",\r\n'), max_size=12).map(
            lambda s: f'"{s}"'
        ),
    ),
    max_size=6,
)


@settings(deadline=None)
@given(rpc=st.integers(0, 99999), trid=st.integers(0, 2**15 - 1), params=_PARAMS)
def test_requests_as_geocompy_writes_them_parse_back(rpc: int, trid: int, params: list) -> None:
    text = f"%R1Q,{rpc},{trid}:{','.join(params)}"
    request = parse_request(text.encode())
    assert request == Request(rpc=rpc, trid=trid, crc=None, params=tuple(params))
    signed = parse_request(f"%R1Q,{rpc},{trid},{crc16_bytewise(text)}:{','.join(params)}".encode())
    assert signed.checksum_ok
    assert signed.params == tuple(params)


@settings(deadline=None)
@given(
    trid=st.integers(0, 2**15 - 1),
    rc=st.integers(0, 99999),
    com=st.sampled_from([0, 3080, 3081]),
    vals=st.lists(_FLOATS.map(lambda x: f"{x:.15f}"), max_size=9),
    checksum=st.booleans(),
)
def test_replies_parse_in_geocompy(
    trid: int, rc: int, com: int, vals: list[str], checksum: bool
) -> None:
    reply = format_reply(trid, rc, vals, com=com, checksum=checksum)
    assert reply.endswith(b"\r\n")
    assert reply.count(b"\n") == 1
    m = GeoCom._R1P.match(reply.decode("ascii")[:-2])
    assert m is not None
    assert (int(m[1]), int(m[2]), int(m[4])) == (com, trid, rc)
    assert (m[5] or "").split(",") == (vals or [""])
    assert (m[3] is not None) == checksum


class _Recorder(Link):
    """A link that keeps what the emulator writes."""

    def __init__(self) -> None:
        self.written = bytearray()
        self.dropped = False

    @property
    def address(self) -> str:
        return "memory"

    def read(self, size: int, timeout: float) -> bytes:
        return b""

    def write(self, data: bytes) -> None:
        self.written += data

    def drop(self) -> None:
        self.dropped = True

    def close(self) -> None:
        """Nothing to release."""


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=80))
def test_any_line_gets_at_most_one_well_formed_reply(data: bytes) -> None:
    link = _Recorder()
    emu = GeoComEmulator(FakeStation(), threading.RLock(), link=link)
    try:
        for line in data.split(b"\n"):
            link.written.clear()
            emu.handle_line(line.rstrip(b"\r"))
            replies = bytes(link.written).split(b"\r\n")
            assert replies[-1] == b""
            assert len(replies) <= 2
            for reply in replies[:-1]:
                assert GeoCom._R1P.match(reply.decode("ascii")) is not None
    finally:
        emu.close()


def test_a_line_that_is_not_a_request_is_a_request_error() -> None:
    for bad in (b"", b"%R1Q", b"%R1Q,:", b"%R1P,0,0:0", b'%R1Q,5:"a"b', b"\x80"):
        with pytest.raises(RequestError):
            parse_request(bad)


# -- faults -----------------------------------------------------------------------------------


def test_faults(line: serial.SerialBase, emulator: GeoComEmulator) -> None:
    faults = emulator.faults
    faults.set(Fault.GARBAGE, times=1)
    assert ask(line, b"%R1Q,0:\r\n") == GARBAGE
    assert ask(line, b"%R1Q,0:\r\n") == b"%R1P,0,0:0\r\n"  # cleared itself
    faults.set(Fault.CODE, code=54321, rpc=5003)
    assert ask(line, b"%R1Q,0:\r\n") == b"%R1P,0,0:0\r\n"  # another RPC is not hit
    assert ask(line, b"%R1Q,5003,5:\r\n") == b"%R1P,0,5:54321\r\n"
    assert ask(line, b"%R1Q,5003,6:\r\n") == b"%R1P,0,6:54321\r\n"
    faults.set(Fault.WARNING, code=1283, rpc=5003, times=1)
    assert ask(line, b"%R1Q,5003:\r\n") == b"%R1P,0,0:1283,1234567\r\n"
    faults.set(Fault.TRUNCATED, times=1)
    assert ask(line, b"%R1Q,5003:\r\n") == b"%R1P,0,0:\r\n"
    faults.set(Fault.SILENT)
    line.timeout = 0.2
    assert ask(line, b"%R1Q,0:\r\n") == b""
    faults.clear()
    line.timeout = 1.0
    assert ask(line, b"%R1Q,0:\r\n") == b"%R1P,0,0:0\r\n"
    faults.set(Fault.DROP)
    line.write(b"%R1Q,0:\r\n")
    with pytest.raises(serial.SerialException):
        line.read_until(b"\r\n")
    with pytest.raises(ValueError, match="times"):
        GeoComFaults().set(Fault.SILENT, times=0)


# -- geocompy's own client --------------------------------------------------------------------


def test_geocompy_drives_the_emulator(
    fast_geocompy: None, emulator: GeoComEmulator, station: FakeStation
) -> None:
    port = serial.serial_for_url(emulator.address, timeout=1.0)
    with SerialConnection(port) as connection:
        tps = GeoCom(connection)
        assert tps.csv.get_instrument_name().params == "TS16 R500"
        assert tps.csv.get_serial_number().params == 1234567
        assert tps.com.get_geocom_version().params == (1, 50, 0)
        assert tps.aut.turn_to(0.0, math.atan2(4.0, 1.0)).error == GeoComCode.OK
        assert tps.aut.fine_adjust(0.1, 0.1).error == GeoComCode.OK
        assert tps.tmc.do_measurement().error == GeoComCode.OK
        response = tps.tmc.get_simple_measurement()
        assert response.error == GeoComCode.OK
        hz, v, d = (float(x) for x in response.params)
        assert (hz, v, d) == pytest.approx((0.0, math.atan2(4.0, 1.0), math.sqrt(17.0)))
        angles = tps.tmc.get_angle_inclination()
        assert angles.error == GeoComCode.OK
        assert len(angles.params) == 9
        assert tps.tmc.get_angle().error == GeoComCode.OK
        assert tps.request(4321).error == GeoComCode.COM_PROC_UNAVAIL
        station.measure_error = NoPrismInConeError("gone")
        assert tps.aut.fine_adjust(0.1, 0.1).error == GeoComCode.AUT_NO_TARGET


def test_tcp_link(station: FakeStation) -> None:
    emu = GeoComEmulator(station, threading.RLock(), link=TcpLink()).start()
    try:
        assert emu.address.startswith("socket://127.0.0.1:")
        port = serial.serial_for_url(emu.address, timeout=1.0)
        try:
            assert ask(port, b"%R1Q,5004:\r\n") == b'%R1P,0,0:0,"TS16 R500"\r\n'
        finally:
            port.close()
    finally:
        emu.close()


def test_close_twice_and_no_restart(station: FakeStation) -> None:
    link = PtyLink()
    emu = GeoComEmulator(station, threading.RLock(), link=link).start()
    with pytest.raises(RuntimeError, match="already"):
        emu.start()
    emu.close()
    emu.close()
    with pytest.raises(RuntimeError, match="closed"):
        emu.start()
    assert link.read(10, 0.0) == b""


@pytest.mark.parametrize(
    ("name", "number"), [("TS16 R500", "12a"), ('say "hi"', "1"), ("TS16", "")]
)
def test_bad_identity(station: FakeStation, name: str, number: str) -> None:
    with pytest.raises(ValueError, match=r"instrument_name|serial_number"):
        GeoComEmulator(
            station, threading.RLock(), link=_Recorder(), instrument_name=name, serial_number=number
        )
