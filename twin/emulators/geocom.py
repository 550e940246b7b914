"""The twin's total station answering Leica GeoCOM (ASCII protocol) on a pty or TCP link.

Requests are lines ``%R1Q,<RPC>[,<TrId>[,<CRC>]]:<P0>,<P1>,...`` ended by CR LF (a bare LF
before a request, as clients send to clear the line, is ignored); replies are
``%R1P,<RC_COM>,<TrId>[,<CRC>]:<RC>[,<values>]`` CR LF, as in Leica's "TPS1200+/TS30/TM30
GeoCOM Reference Manual" (version 1.50). Angles are radians: ``Hz`` clockwise, ``V`` the
zenith angle (:mod:`twin.drivers.geocom_codes` converts them). The emulator answers with a
wrapped :class:`twin.hal.TotalStation`, called only while holding the shared ``lock``.

The RPCs answered (``RPC_NAMES``):

- ``COM_NullProc`` 0, ``COM_SetDoublePrecision`` 107, ``COM_GetDoublePrecision`` 108,
  ``COM_GetSWVersion`` 110, ``CSV_GetInstrumentNo`` 5003, ``CSV_GetInstrumentName`` 5004,
  ``CSV_GetSWVersion`` 5034;
- ``AUT_MakePositioning`` 9027 (Hz, V, ...): the station points along that direction
  (``POINTING_RANGE`` m out); ``AUT_FineAdjust`` 9037: the station measures (automatic aim)
  and the shot is kept until the next positioning or fine adjustment; no prism or a blocked
  line of sight answers ``AUT_NO_TARGET`` (8710);
- ``TMC_DoMeasure`` 2008 (command, mode): the kept shot's distance becomes readable
  (``TMC_CLEAR`` 3 and ``TMC_STOP`` 0 clear it); ``TMC_GetSimpleMea`` 2108 (wait, mode):
  Hz, V, slope distance of the kept shot, or ``TMC_DIST_ERROR`` (1292) when there is none,
  ``EDM_DISTRANGE_ERR`` (818) out of range, ``INSTRUMENT_TILT`` (22) tilted beyond the
  compensator; ``BAP_MeasDistanceAngle`` 17017 (mode): the same, measuring first when no
  shot is kept;
- ``TMC_GetAngle1`` 2003 (mode): Hz, V, angle accuracy, angle time (ms), cross and length
  inclination, inclination accuracy, inclination time (ms), face; ``TMC_GetAngle5`` 2107
  (mode): Hz, V; both read the station's inclination (``INSTRUMENT_TILT`` beyond range);
- ``TMC_GetFace`` 2026, ``TMC_GetInclineSwitch`` 2007, ``AUT_GetATRStatus`` 9019.

Any other RPC gets ``COM_PROC_UNAVAIL`` (3081) in ``RC_COM``; a line that is not a
request, ``COM_CANT_DECODE_REQ`` (3080); a wrong checksum ``COM_SRVR_RX_CHECKSUM_ERROR``
(3101); parameters that do not parse, ``IVPARAM`` (2). :class:`GeoComFaults` makes the
emulator misbehave on purpose.
"""

from __future__ import annotations

import enum
import math
import re
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from geocompy.communication import crc16_bytewise

from twin.closing import Closing
from twin.drivers.geocom_codes import (
    geocom_from_polar,
    inclination_from_tilt,
    polar_from_geocom,
)
from twin.emulators.links import Link, PtyLink
from twin.hal.devices import TotalStation
from twin.hal.readings import TotalStationMeasurement
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
from twin.instruments.polar import polar2cartesian

POINTING_RANGE = 10.0
"""How far along a positioning's direction the station is pointed, m."""

MAX_LINE = 4096
"""Bytes without a line end after which the input is dropped as garbage."""

GARBAGE = b"\x8a\xf3#&\xff%R1P?\x00\xc3\r\n"
"""What :attr:`Fault.GARBAGE` answers: bytes that are not ASCII, ended by CR LF."""

OK = 0
IVPARAM = 2
FATAL = 4
TIME_OUT = 6
SYSBUSY = 13
INSTRUMENT_TILT = 22
EDM_DISTRANGE_ERR = 818
TMC_DIST_ERROR = 1292
COM_CANT_DECODE_REQ = 3080
COM_PROC_UNAVAIL = 3081
COM_SRVR_RX_CHECKSUM_ERROR = 3101
AUT_NO_TARGET = 8710

TMC_STOP = 0
TMC_CLEAR = 3

RPC_NAMES: dict[int, str] = {
    0: "COM_NullProc",
    107: "COM_SetDoublePrecision",
    108: "COM_GetDoublePrecision",
    110: "COM_GetSWVersion",
    2003: "TMC_GetAngle1",
    2007: "TMC_GetInclineSwitch",
    2008: "TMC_DoMeasure",
    2026: "TMC_GetFace",
    2107: "TMC_GetAngle5",
    2108: "TMC_GetSimpleMea",
    5003: "CSV_GetInstrumentNo",
    5004: "CSV_GetInstrumentName",
    5034: "CSV_GetSWVersion",
    9019: "AUT_GetATRStatus",
    9027: "AUT_MakePositioning",
    9037: "AUT_FineAdjust",
    17017: "BAP_MeasDistanceAngle",
}
"""The RPCs the emulator answers, by number."""

FIRMWARE = (1, 0, 0)
"""What ``CSV_GetSWVersion`` reports (release, version, subversion)."""

GEOCOM_VERSION = (1, 50, 0)
"""What ``COM_GetSWVersion`` reports: the reference manual's GeoCOM release."""


# -- framing ----------------------------------------------------------------------------------

_REQUEST = re.compile(r"^%R1Q,(\d{1,9})(?:,(\d{1,9}))?(?:,(\d{1,9}))?:(.*)$")
_PARAM = re.compile(r'"[^"]*"|[^,]*')


class RequestError(ValueError):
    """A line that is not a GeoCOM request. ``trid`` is its transaction id where one could
    be read (the reply carries it), else 0."""

    def __init__(self, message: str, trid: int = 0) -> None:
        super().__init__(message)
        self.trid = trid


@dataclass(frozen=True)
class Request:
    """One parsed GeoCOM request.

    Attributes:
        rpc: the remote procedure's number.
        trid: the transaction id (0 when the request has none).
        crc: the CRC-16 the request carries, or None.
        params: the parameters as sent (strings keep their quotes).
        checksum_ok: whether the CRC (if any) matches the request.
    """

    rpc: int
    trid: int
    crc: int | None
    params: tuple[str, ...]
    checksum_ok: bool = True


def split_params(text: str) -> tuple[str, ...]:
    """Split a parameter list at the commas outside double-quoted strings."""
    if text == "":
        return ()
    params = []
    pos = 0
    while True:
        m = _PARAM.match(text, pos)
        assert m is not None  # the pattern matches the empty string
        params.append(m.group())
        pos = m.end()
        if pos >= len(text):
            return tuple(params)
        if text[pos] != ",":
            raise ValueError(f"a parameter list must separate values by commas, got {text!r}")
        pos += 1
        if pos == len(text):
            params.append("")
            return tuple(params)


def parse_request(line: bytes) -> Request:
    """Parse one request line (without its CR LF).

    Raises:
        RequestError: the line is not ASCII or not ``%R1Q,<RPC>[,<TrId>[,<CRC>]]:<params>``.
    """
    try:
        text = line.decode("ascii")
    except UnicodeDecodeError as exc:
        raise RequestError(f"a request must be ASCII text, got {line[:40]!r}") from exc
    m = _REQUEST.match(text)
    if m is None:
        raise RequestError(f"expected %R1Q,<RPC>[,<TrId>]:<params>, got {text[:40]!r}")
    trid = int(m[2]) if m[2] is not None else 0
    try:
        params = split_params(m[4])
    except ValueError as exc:
        raise RequestError(str(exc), trid) from exc
    crc = int(m[3]) if m[3] is not None else None
    ok = True
    if crc is not None:
        ok = crc == crc16_bytewise(f"%R1Q,{m[1]},{m[2]}:{m[4]}")
    return Request(rpc=int(m[1]), trid=trid, crc=crc, params=params, checksum_ok=ok)


def format_reply(
    trid: int, rc: int, values: Sequence[str] = (), *, com: int = OK, checksum: bool = False
) -> bytes:
    """One reply line: ``%R1P,<com>,<trid>[,<crc>]:<rc>[,<values>]`` CR LF."""
    body = ",".join([str(rc), *values])
    if checksum:
        crc = crc16_bytewise(f"%R1P,{com},{trid}:{body}")
        return f"%R1P,{com},{trid},{crc}:{body}\r\n".encode("ascii")
    return f"%R1P,{com},{trid}:{body}\r\n".encode("ascii")


# -- faults -----------------------------------------------------------------------------------


class Fault(enum.Enum):
    """How the emulator misbehaves (:class:`GeoComFaults`)."""

    GARBAGE = "garbage"
    """Answer :data:`GARBAGE` (bytes that are not ASCII) instead of the reply."""
    TRUNCATED = "truncated"
    """Carry out the request, then answer the first half of its reply, ended by CR LF."""
    CODE = "code"
    """Answer the given return code (any number, known or not) and do nothing."""
    WARNING = "warning"
    """Carry out the request and answer its values with the given return code in place
    of its own (a warning such as ``TMC_NO_FULL_CORRECTION`` comes with values)."""
    SILENT = "silent"
    """Answer nothing and do nothing."""
    DROP = "drop"
    """Break the link (:meth:`twin.emulators.links.Link.drop`) instead of answering."""


@dataclass
class GeoComFaults:
    """Faults a test sets while the emulator runs (thread-safe).

    Attributes:
        kind: the fault, None for none.
        code: the return code :attr:`Fault.CODE` answers.
        rpc: only requests of this RPC are hit (None: every request).
        times: how many requests are hit before the fault clears itself (None: until
            :meth:`clear`).
    """

    kind: Fault | None = None
    code: int = 0
    rpc: int | None = None
    times: int | None = None
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False, compare=False)

    def set(
        self, kind: Fault, *, code: int = 0, rpc: int | None = None, times: int | None = None
    ) -> None:
        """Start misbehaving (see the attributes)."""
        if times is not None and times < 1:
            raise ValueError(f"times must be a positive count or None, got {times!r}")
        with self._lock:
            self.kind, self.code, self.rpc, self.times = kind, int(code), rpc, times

    def clear(self) -> None:
        """Behave again."""
        with self._lock:
            self.kind, self.code, self.rpc, self.times = None, 0, None, None

    def take(self, rpc: int | None) -> tuple[Fault, int] | None:
        """The fault that hits a request of ``rpc`` now, counting it; None for none."""
        with self._lock:
            if self.kind is None or (self.rpc is not None and rpc != self.rpc):
                return None
            hit = (self.kind, self.code)
            if self.times is not None:
                self.times -= 1
                if self.times == 0:
                    self.kind, self.code, self.rpc, self.times = None, 0, None, None
            return hit


# -- the emulator -----------------------------------------------------------------------------


class _Reply(Exception):
    """Ends a handler with a return code and no values."""

    def __init__(self, rc: int) -> None:
        super().__init__(rc)
        self.rc = rc


def _code_for(error: Exception) -> int:
    """The GeoCOM return code with which the instrument reports a station's error."""
    if isinstance(error, NoPrismInConeError | LineOfSightBlockedError):
        return AUT_NO_TARGET
    if isinstance(error, OutOfRangeError):
        return EDM_DISTRANGE_ERR
    if isinstance(error, TiltOutOfRangeError):
        return INSTRUMENT_TILT
    if isinstance(error, DistanceMeasurementError):
        return TMC_DIST_ERROR
    if isinstance(error, InstrumentBusyError):
        return SYSBUSY
    if isinstance(error, InstrumentTimeoutError):
        return TIME_OUT
    if isinstance(error, InstrumentFaultError):
        code = error.details.get("code")
        if isinstance(code, int) and code != OK:
            return code
    return FATAL


class GeoComEmulator(Closing):
    """A GeoCOM instrument played by a :class:`twin.hal.TotalStation`.

    Args:
        station: the instrument that answers (the twin's, or any other).
        lock: held around every call of ``station`` (the world is shared).
        link: the byte link to serve on; default a new :class:`PtyLink`. The emulator
            closes it.
        instrument_name: what ``CSV_GetInstrumentName`` answers (no quotes or line ends).
        serial_number: what ``CSV_GetInstrumentNo`` answers (decimal digits).
        faults: misbehaviour a test sets at run time; default none (:attr:`faults`).

    Raises:
        ValueError: a name with quotes or line ends, a serial number that is not digits.
    """

    def __init__(
        self,
        station: TotalStation,
        lock: threading.RLock,
        *,
        link: Link | None = None,
        instrument_name: str = "TS16 R500",
        serial_number: str = "1234567",
        faults: GeoComFaults | None = None,
    ) -> None:
        if any(c in instrument_name for c in '"\r\n') or not instrument_name.isascii():
            raise ValueError(
                f"instrument_name must be ASCII without quotes or line ends, got "
                f"{instrument_name!r}"
            )
        if not (serial_number.isascii() and serial_number.isdigit()):
            raise ValueError(f"serial_number must be decimal digits, got {serial_number!r}")
        self.station = station
        self.lock = lock
        self.instrument_name = instrument_name
        self.serial_number = serial_number
        self.faults = faults if faults is not None else GeoComFaults()
        self._link = link if link is not None else PtyLink()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._closed = False
        self.precision = 15
        self.requests = 0
        """Requests answered or faulted so far (a count for tests)."""
        self._hz, self._v = 0.0, math.pi / 2
        self._pointed = False
        self._shot: TotalStationMeasurement | None = None
        self._shot_error: int | None = None
        self._measured = False
        self._handlers: dict[int, Callable[[tuple[str, ...]], list[str]]] = {
            0: lambda p: [],
            107: self._set_precision,
            108: lambda p: [str(self.precision)],
            110: lambda p: [str(v) for v in GEOCOM_VERSION],
            2003: self._get_angle1,
            2007: lambda p: ["1"],
            2008: self._do_measure,
            2026: lambda p: ["0"],
            2107: self._get_angle5,
            2108: self._get_simple_mea,
            5003: lambda p: [self.serial_number],
            5004: lambda p: [f'"{self.instrument_name}"'],
            5034: lambda p: [str(v) for v in FIRMWARE],
            9019: lambda p: ["1"],
            9027: self._make_positioning,
            9037: self._fine_adjust,
            17017: self._meas_distance_angle,
        }

    @property
    def address(self) -> str:
        """What a driver opens: the pty's path or ``socket://127.0.0.1:PORT``."""
        return self._link.address

    @property
    def link(self) -> Link:
        """The link served on."""
        return self._link

    def start(self) -> GeoComEmulator:
        """Serve in a daemon thread; returns self."""
        if self._closed:
            raise RuntimeError("the GeoCOM emulator is closed; start a new one")
        if self._thread is not None:
            raise RuntimeError("the GeoCOM emulator is already serving")
        self._thread = threading.Thread(target=self._serve, name="geocom-emulator", daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        """Stop serving and close the link; twice is harmless."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        self._link.close()

    # -- serving ----------------------------------------------------------------------------

    def _serve(self) -> None:
        buffer = b""
        while not self._stop.is_set():
            began = time.monotonic()
            data = self._link.read(4096, 0.05)
            if not data:
                if time.monotonic() - began < 0.01:  # a dropped link answers at once
                    self._stop.wait(0.05)
                continue
            buffer += data
            while b"\n" in buffer and not self._stop.is_set():
                line, _, buffer = buffer.partition(b"\n")
                try:
                    self.handle_line(line.rstrip(b"\r"))
                except Exception:  # the instrument reports a failure, it does not stop
                    self._link.write(format_reply(0, FATAL))
            if len(buffer) > MAX_LINE:
                buffer = b""
                self._link.write(format_reply(0, OK, com=COM_CANT_DECODE_REQ))

    def handle_line(self, line: bytes) -> None:
        """Answer one request line (without its line end) on the link; never raises for
        what the line holds."""
        if not line.strip():
            return  # a bare line end clears the line
        try:
            request = parse_request(line.strip())
        except RequestError as exc:
            self.requests += 1
            if not self._apply_fault(None, exc.trid, lambda: b""):
                self._link.write(format_reply(exc.trid, OK, com=COM_CANT_DECODE_REQ))
            return
        self.requests += 1
        if not self._apply_fault(request.rpc, request.trid, lambda: self.answer(request)):
            self._link.write(self.answer(request))

    def _apply_fault(self, rpc: int | None, trid: int, answer: Callable[[], bytes]) -> bool:
        """Misbehave if a fault hits this request (``answer`` carries it out and gives the
        true reply); whether one did."""
        hit = self.faults.take(rpc)
        if hit is None:
            return False
        kind, code = hit
        if kind is Fault.GARBAGE:
            self._link.write(GARBAGE)
        elif kind is Fault.CODE:
            self._link.write(format_reply(trid, code))
        elif kind is Fault.WARNING:
            self._link.write(re.sub(rb":\d+", b":%d" % code, answer(), count=1))
        elif kind is Fault.TRUNCATED:
            full = answer().rstrip(b"\r\n")
            self._link.write(full[: max(1, len(full) // 2)] + b"\r\n")
        elif kind is Fault.DROP:
            self._link.drop()
        return True

    def answer(self, request: Request) -> bytes:
        """The reply to one parsed request (carrying it out on the station)."""
        checksum = request.crc is not None
        if not request.checksum_ok:
            return format_reply(request.trid, OK, com=COM_SRVR_RX_CHECKSUM_ERROR)
        handler = self._handlers.get(request.rpc)
        if handler is None:
            return format_reply(request.trid, OK, com=COM_PROC_UNAVAIL, checksum=checksum)
        try:
            values = handler(request.params)
        except _Reply as reply:
            return format_reply(request.trid, reply.rc, checksum=checksum)
        except (ValueError, IndexError):
            return format_reply(request.trid, IVPARAM, checksum=checksum)
        except Exception:  # the station failed in a way it does not document
            return format_reply(request.trid, FATAL, checksum=checksum)
        return format_reply(request.trid, OK, values, checksum=checksum)

    # -- RPCs -------------------------------------------------------------------------------

    def _float(self, value: float) -> str:
        return f"{value:.{self.precision}f}"

    def _set_precision(self, params: tuple[str, ...]) -> list[str]:
        digits = int(params[0])
        if not 0 <= digits <= 15:
            raise ValueError(f"precision must lie in [0, 15] digits, got {digits}")
        self.precision = digits
        return []

    def _make_positioning(self, params: tuple[str, ...]) -> list[str]:
        hz, v = float(params[0]), float(params[1])
        horizontal, zenith = polar_from_geocom(hz, v)  # ValueError: not finite
        direction = polar2cartesian(np.array([POINTING_RANGE, horizontal, zenith]))
        self._forget_shot()
        with self.lock:
            try:
                self.station.point(direction)
            except ValueError as exc:
                raise _Reply(IVPARAM) from exc
            except Exception as exc:
                raise _Reply(_code_for(exc)) from exc
        self._hz, self._v = geocom_from_polar(horizontal, zenith)
        self._pointed = True
        return []

    def _forget_shot(self) -> None:
        self._shot, self._shot_error, self._measured = None, None, False

    def _lock_on(self) -> None:
        """Automatic aim and a shot at the prism near the telescope's direction: kept."""
        self._forget_shot()
        with self.lock:
            try:
                if not self._pointed:
                    horizontal, zenith = polar_from_geocom(self._hz, self._v)
                    self.station.point(
                        polar2cartesian(np.array([POINTING_RANGE, horizontal, zenith]))
                    )
                    self._pointed = True
                shot = self.station.measure()
            except (OutOfRangeError, TiltOutOfRangeError, DistanceMeasurementError) as exc:
                self._shot_error = _code_for(exc)  # the aim locked; the distance failed
                return
            except Exception as exc:
                raise _Reply(_code_for(exc)) from exc
        self._shot = shot
        self._hz, self._v = geocom_from_polar(shot.horizontal, shot.zenith)

    def _fine_adjust(self, params: tuple[str, ...]) -> list[str]:
        _window = float(params[0]), float(params[1])  # the station's own cone searches
        self._lock_on()
        return []

    def _do_measure(self, params: tuple[str, ...]) -> list[str]:
        command = int(params[0])
        if command in (TMC_STOP, TMC_CLEAR):
            self._measured = False
        else:
            self._measured = self._shot is not None or self._shot_error is not None
        return []

    def _shot_values(self) -> list[str]:
        if self._shot_error is not None:
            raise _Reply(self._shot_error)
        if self._shot is None:
            raise _Reply(TMC_DIST_ERROR)
        hz, v = geocom_from_polar(self._shot.horizontal, self._shot.zenith)
        return [self._float(hz), self._float(v), self._float(self._shot.distance)]

    def _get_simple_mea(self, params: tuple[str, ...]) -> list[str]:
        _wait_ms, _mode = int(params[0]), int(params[1])
        if not self._measured:
            raise _Reply(TMC_DIST_ERROR)
        return self._shot_values()

    def _meas_distance_angle(self, params: tuple[str, ...]) -> list[str]:
        mode = int(params[0])
        if self._shot is None and self._shot_error is None:
            self._lock_on()
        self._measured = True
        return [*self._shot_values(), str(mode)]

    def _inclination(self) -> tuple[float, float, float, float]:
        """(cross, length, sigma, time s) of one reading of the station's inclination."""
        with self.lock:
            try:
                reading = self.station.read_inclination()
            except Exception as exc:
                raise _Reply(_code_for(exc)) from exc
            spec = self.station.inclinometer
        cross, length = inclination_from_tilt(reading.roll, reading.pitch, self._hz)
        return cross, length, spec.sigma if spec is not None else 0.0, reading.timestamp

    def _get_angle1(self, params: tuple[str, ...]) -> list[str]:
        _mode = int(params[0])
        cross, length, sigma, t = self._inclination()
        with self.lock:
            angle_sigma = self.station.spec.angle_sigma
        ms = str(round(t * 1000.0) % 2**31)
        return [
            self._float(self._hz),
            self._float(self._v),
            self._float(angle_sigma),
            ms,
            self._float(cross),
            self._float(length),
            self._float(sigma),
            ms,
            "0",
        ]

    def _get_angle5(self, params: tuple[str, ...]) -> list[str]:
        _mode = int(params[0])
        self._inclination()
        return [self._float(self._hz), self._float(self._v)]
