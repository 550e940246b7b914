"""A Leica total station over GeoCOM (serial, a pty, or a serial-to-Ethernet bridge).

GeoCOM is spoken by geocompy (:class:`geocompy.geo.GeoCom`) over a pyserial port opened
with ``serial_for_url``; this module turns the project's requests into GeoCOM calls, the
angles into the project's convention (:mod:`twin.drivers.geocom_codes`, where they are
converted once) and GeoCOM's return codes and link failures into the project's typed
errors:

- a non-zero return code -> the error :func:`twin.drivers.geocom_codes.error_for_code`
  names (no target, no distance, busy, timeout, tilt, anything else a fault); the message
  holds the code and its GeoCOM name, ``details["code"]`` the number;
- no reply within ``timeout_s`` -> :class:`InstrumentTimeoutError`; ``LOST_AFTER_TIMEOUTS``
  such in a row, or a port that closes or fails -> :class:`DeviceLostError` (and every
  later request raises it too);
- a reply that cannot be read (garbage, cut short) -> the request once more where it only
  reads (angles, the measurement, names), else :class:`InstrumentFaultError`.

Every duration the driver keeps is in rig seconds; the port's timeout is
``clock.wall(timeout_s)`` wall seconds.
"""

from __future__ import annotations

import contextlib
import math
import re
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np
import serial
from geocompy.communication import Connection, SerialConnection
from geocompy.geo import GeoCom
from geocompy.geo.gcdata import Inclination, Measurement
from geocompy.geo.gctypes import GeoComCode, GeoComResponse
from numpy.typing import ArrayLike

from twin.drivers.clock import WallClock
from twin.drivers.geocom_codes import (
    ANGLE_WARNINGS,
    DECODE_CODES,
    DISTANCE_WARNINGS,
    error_for_code,
    geocom_from_polar,
    polar_from_geocom,
    tilt_from_inclination,
)
from twin.hal.devices import TotalStation
from twin.hal.errors import DeviceLostError
from twin.hal.readings import TiltReading, TotalStationMeasurement
from twin.instruments.errors import (
    DistanceMeasurementError,
    InstrumentBusyError,
    InstrumentError,
    InstrumentFaultError,
    InstrumentTimeoutError,
    TiltOutOfRangeError,
)
from twin.instruments.polar import cartesian2polar
from twin.instruments.tilt import check_tilt
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec

LOST_AFTER_TIMEOUTS = 3
"""Requests in a row without any reply after which the instrument counts as lost."""

_LINK_ERRORS: tuple[type[InstrumentError], ...] = (
    InstrumentBusyError,
    InstrumentTimeoutError,
    InstrumentFaultError,
)
"""What a return code may become in any request (:data:`twin.hal.DOCUMENTED_ERRORS`)."""

_T = TypeVar("_T")
_REPLY_TRID = re.compile(r"^%R1P,\d+,(\d+)")
_REQUEST_TRID = re.compile(r"^%R1Q,\d+,(\d+)")


class _Undecodable(Exception):
    """A reply with the right codes whose values are missing or not numbers."""


class _Link(Connection):
    """geocompy's serial connection, remembering why the last exchange failed.

    geocompy turns every failure of the line into a communication return code; the driver
    needs the exception itself (no reply in time, the port gone, bytes that are not ASCII).
    Replies whose transaction id is not the request's (late replies to a request that timed
    out) are skipped.
    """

    def __init__(self, port: serial.SerialBase) -> None:
        self._serial = SerialConnection(port)
        self._port = port
        self.error: BaseException | None = None

    def _run(self, action: Callable[[], _T]) -> _T:
        self.error = None
        try:
            return action()
        except BaseException as exc:
            self.error = exc
            raise

    def is_open(self) -> bool:
        return self._serial.is_open()

    def send_binary(self, data: bytes) -> None:
        self._run(lambda: self._serial.send_binary(data))

    def send(self, message: str) -> None:
        self._run(lambda: self._serial.send(message))

    def receive_binary(self) -> bytes:
        return self._run(self._serial.receive_binary)

    def receive(self) -> str:
        return self._run(self._serial.receive)

    def exchange_binary(self, data: bytes) -> bytes:
        return self.exchange(data.decode("ascii", "ignore")).encode("ascii")

    def exchange(self, cmd: str) -> str:
        request = _REQUEST_TRID.match(cmd)

        def run() -> str:
            self._serial.send(cmd)
            while True:
                reply = self._serial.receive()
                answer = _REPLY_TRID.match(reply)
                if request is None or answer is None or answer[1] == request[1]:
                    return reply

        return self._run(run)

    def close(self) -> None:
        self._port.close()

    def reset(self) -> None:
        with contextlib.suppress(OSError, ValueError):
            self._serial.reset()


def geocom_link(port: str) -> str:
    """A GeoCOM instrument's link as :class:`DeviceLostError` names it."""
    return f"{port} (GeoCOM)"


class GeoComTotalStation(TotalStation):
    """A Leica total station with automatic aim (ATR) and compensator, over GeoCOM.

    Args:
        port: a serial device's path (a pty's path too) or a pyserial URL such as
            ``socket://127.0.0.1:PORT``.
        clock: the rig's clock (timestamps; ``timeout_s`` is in its seconds).
        spec: the instrument's noise, range and aim cone, as the campaign weighs its shots
            (:attr:`spec`); ``spec.aim_cone`` sets the automatic aim's search window.
        inclinometer: the compensator's specification; None: the shots carry no
            inclination reading and :meth:`read_inclination` checks no working range.
        baud: the serial line's speed, bit/s (ignored by a socket).
        timeout_s: the longest wait for one reply, rig s (a positioning or a measurement
            included).
        name: the device's name in :class:`DeviceLostError`.

    Raises:
        ValueError: ``timeout_s`` or ``baud`` is not a positive number.
        DeviceLostError: the port cannot be opened, or no GeoCOM instrument answers on it.
    """

    def __init__(
        self,
        port: str,
        *,
        clock: WallClock,
        spec: TotalStationSpec,
        inclinometer: InclinometerSpec | None,
        baud: int = 115200,
        timeout_s: float = 10.0,
        name: str = "total_station",
    ) -> None:
        if not (isinstance(timeout_s, int | float) and math.isfinite(timeout_s) and timeout_s > 0):
            raise ValueError(f"timeout_s must be a positive number of seconds, got {timeout_s!r}")
        if not (isinstance(baud, int) and baud > 0):
            raise ValueError(f"baud must be a positive integer, got {baud!r}")
        self.name = name
        self.port = port
        self.link = geocom_link(port)
        """Where and how the instrument is reached, for messages: ``PORT (GeoCOM)``."""
        self.timeout_s = float(timeout_s)
        self._clock = clock
        self._spec = spec
        self._inclinometer = inclinometer
        self._closed = False
        self._lost: str | None = None
        self._silent = 0
        self._flush = False
        self.rejected: dict[str, int] = {"undecodable": 0, "unanswered": 0}
        """Replies that could not be read and requests that got none, counted."""
        wall = clock.wall(self.timeout_s)
        try:
            handle = serial.serial_for_url(port, baudrate=baud, timeout=wall, write_timeout=wall)
        except (OSError, ValueError) as exc:
            self._closed = True
            raise DeviceLostError(
                name, f"cannot open the port: {exc}", link=geocom_link(port), port=port
            ) from exc
        self._link = _Link(handle)
        try:
            self._geocom = GeoCom(self._link, attempts=1)
        except ConnectionRefusedError as exc:
            self.close()
            raise DeviceLostError(
                name,
                f"no GeoCOM instrument answered COM_NullProc within {self.timeout_s} s",
                link=geocom_link(port),
                port=port,
                timeout_s=self.timeout_s,
            ) from exc

    # -- the project's interface --------------------------------------------------------

    @property
    def spec(self) -> TotalStationSpec:
        return self._spec

    @property
    def inclinometer(self) -> InclinometerSpec | None:
        return self._inclinometer

    def identify(self) -> dict[str, str]:
        """The instrument's ``name`` and ``serial`` number, and ``firmware`` and ``geocom``
        (release.version.subversion) where the instrument reports them."""
        g = self._geocom
        info = {
            "name": self._request("CSV_GetInstrumentName", g.csv.get_instrument_name, _string),
            "serial": str(self._request("CSV_GetInstrumentNo", g.csv.get_serial_number, _int)),
        }
        for key, request, call in (
            ("firmware", "CSV_GetSWVersion", g.csv.get_firmware_version),
            ("geocom", "COM_GetSWVersion", g.com.get_geocom_version),
        ):
            with contextlib.suppress(InstrumentFaultError):
                info[key] = ".".join(str(v) for v in self._request(request, call, _version))
        return info

    def point(self, target_level: ArrayLike) -> None:
        """Turn the telescope (face I) towards ``target_level``, (3,) m, levelled frame.

        Raises:
            ValueError: the target is not a finite non-zero (3,) point.
        """
        target = np.asarray(target_level, dtype=float)
        if target.shape != (3,) or not np.all(np.isfinite(target)) or not np.any(target):
            raise ValueError(
                f"the aim must be a finite non-zero (3,) point in m, got {target_level!r}"
            )
        _, horizontal, zenith = cartesian2polar(target)
        hz, v = geocom_from_polar(float(horizontal), float(zenith))
        self._request(
            "AUT_MakePositioning",
            lambda: self._geocom.aut.turn_to(hz, v),
            None,
            safe=False,
            documented=(),
        )

    def measure(self) -> TotalStationMeasurement:
        """Lock the automatic aim on the prism near the pointing direction
        (``AUT_FineAdjust``), measure the distance (``TMC_DoMeasure``) and read the shot
        (``TMC_GetSimpleMea``), levelled by the compensator; with an inclinometer, the
        inclination (``TMC_GetAngle1``) goes with it."""
        g = self._geocom
        window = 2.0 * self._spec.aim_cone
        self._request("AUT_FineAdjust", lambda: g.aut.fine_adjust(window, window), None, safe=False)
        self._request(
            "TMC_DoMeasure",
            lambda: g.tmc.do_measurement(Measurement.DISTANCE, Inclination.AUTO),
            None,
            safe=False,
        )
        timestamp = self._clock.now()
        wait_s = 0.5 * self.timeout_s
        hz, v, distance = self._request(
            "TMC_GetSimpleMea",
            lambda: g.tmc.get_simple_measurement(wait_s, Inclination.AUTO),
            _simple_measurement,
            accept=DISTANCE_WARNINGS,
        )
        if distance <= 0.0:
            raise DistanceMeasurementError(
                f"TMC_GetSimpleMea: the instrument reported a slope distance of {distance} m; "
                "expected a positive distance",
                code=0,
                request="TMC_GetSimpleMea",
            )
        horizontal, zenith = polar_from_geocom(hz, v)
        tilt = self.read_inclination() if self._inclinometer is not None else None
        return TotalStationMeasurement(
            timestamp=timestamp, distance=distance, horizontal=horizontal, zenith=zenith, tilt=tilt
        )

    def read_inclination(self) -> TiltReading:
        """One compensator reading (``TMC_GetAngle1``, inclination measured now), turned
        into the project's (roll, pitch) with the telescope's ``Hz``
        (:func:`twin.drivers.geocom_codes.tilt_from_inclination`).

        Raises:
            TiltOutOfRangeError: the instrument says so, or the reading exceeds the
                inclinometer's working range.
        """
        hz, cross, length = self._request(
            "TMC_GetAngle1",
            lambda: self._geocom.tmc.get_angle_inclination(Inclination.MEASURE),
            _inclination,
            accept=ANGLE_WARNINGS,
            documented=(TiltOutOfRangeError,),
        )
        roll, pitch = tilt_from_inclination(cross, length, hz)
        reading = TiltReading(timestamp=self._clock.now(), roll=roll, pitch=pitch)
        if self._inclinometer is not None:
            check_tilt(reading, self._inclinometer)
        return reading

    def close(self) -> None:
        """Close the port; twice is harmless."""
        if self._closed:
            return
        self._closed = True
        with contextlib.suppress(OSError):
            self._link.close()

    # -- one request ----------------------------------------------------------------------

    def _request(
        self,
        request: str,
        call: Callable[[], GeoComResponse[Any]],
        parse: Callable[[GeoComResponse[Any]], _T] | None,
        *,
        accept: frozenset[int] = frozenset(),
        safe: bool = True,
        documented: tuple[type[InstrumentError], ...] | None = None,
    ) -> _T:
        """Send one GeoCOM request, check its reply, return ``parse(reply)``.

        ``accept``: non-zero return codes whose values are still valid (warnings). ``safe``:
        the request may be sent again after a reply that could not be read. ``documented``:
        the instrument's errors the calling method may raise beside busy, timeout and fault
        (None: any); a return code that maps to another is an :class:`InstrumentFaultError`.
        """
        if self._closed:
            raise DeviceLostError(
                self.name, f"the port is closed ({request})", link=self.link, port=self.port
            )
        if self._lost is not None:
            raise DeviceLostError(
                self.name, f"{self._lost} ({request})", link=self.link, port=self.port
            )
        tries = 2 if safe else 1
        for attempt in range(tries):
            if self._flush:
                self._link.reset()
                self._flush = False
            response = call()
            self._check_link(request)
            # bytes that are not ASCII text leave geocompy with a reply of its own making
            garbled = self._link.error is not None
            match = None if garbled else GeoCom._R1P.match(response.response)
            if match is not None:
                code = int(match[1]) or int(match[4])
                if code != 0 and code not in accept:
                    error = error_for_code(code, request, port=self.port)
                    allowed = None if documented is None else (*_LINK_ERRORS, *documented)
                    if allowed is not None and not isinstance(error, allowed):
                        error = InstrumentFaultError(str(error), **error.details)
                    raise error
                if response.error not in DECODE_CODES:
                    try:
                        return None if parse is None else parse(response)  # type: ignore[return-value]
                    except _Undecodable:
                        pass
            self._flush = True
            self.rejected["undecodable"] += 1
            if attempt + 1 == tries:
                code = int(GeoComCode.COM_CANT_DECODE)
                raise InstrumentFaultError(
                    f"{request}: the reply {response.response!r} could not be decoded "
                    f"(GeoCOM return code {code}, COM_CANT_DECODE)",
                    code=code,
                    name="COM_CANT_DECODE",
                    request=request,
                    reply=response.response,
                    port=self.port,
                )
        raise AssertionError("unreachable")  # pragma: no cover

    def _check_link(self, request: str) -> None:
        """Raise for a reply that never came or a port that failed; count silences."""
        error = self._link.error
        if isinstance(error, TimeoutError):
            self._silent += 1
            self.rejected["unanswered"] += 1
            self._flush = True
            if self._silent >= LOST_AFTER_TIMEOUTS:
                self._lost = (
                    f"connection lost: no reply to {self._silent} requests in a row "
                    f"(each waited {self.timeout_s} s)"
                )
                raise DeviceLostError(
                    self.name,
                    f"{self._lost} ({request})",
                    link=self.link,
                    port=self.port,
                    timeout_s=self.timeout_s,
                ) from error
            code = int(GeoComCode.COM_TIMEDOUT)
            raise InstrumentTimeoutError(
                f"{request}: no reply within {self.timeout_s} s on {self.port!r} "
                f"(GeoCOM return code {code}, COM_TIMEDOUT)",
                code=code,
                name="COM_TIMEDOUT",
                request=request,
                timeout_s=self.timeout_s,
                port=self.port,
            ) from error
        if isinstance(error, OSError):
            self._lost = f"connection lost: the link failed: {error}"
            raise DeviceLostError(
                self.name,
                f"{self._lost} ({request})",
                link=self.link,
                port=self.port,
                error=repr(error),
            ) from error
        self._silent = 0  # something came back, if only bytes that are not ASCII text


def _values(response: GeoComResponse[Any], count: int) -> tuple[Any, ...]:
    params = response.params
    values = params if isinstance(params, tuple) else (params,)
    if params is None or len(values) != count:
        raise _Undecodable
    return values


def _finite(*values: Any) -> tuple[float, ...]:
    out = tuple(float(v) for v in values)
    if not all(math.isfinite(v) for v in out):
        raise _Undecodable
    return out


def _string(response: GeoComResponse[Any]) -> str:
    (value,) = _values(response, 1)
    return str(value)


def _int(response: GeoComResponse[Any]) -> int:
    (value,) = _values(response, 1)
    return int(value)


def _version(response: GeoComResponse[Any]) -> tuple[int, ...]:
    return tuple(int(v) for v in _values(response, 3))


def _simple_measurement(response: GeoComResponse[Any]) -> tuple[float, float, float]:
    hz, v, distance = _finite(*_values(response, 3))
    return hz, v, distance


def _inclination(response: GeoComResponse[Any]) -> tuple[float, float, float]:
    values = _values(response, 9)
    hz, cross, length = _finite(values[0], values[4], values[5])
    return hz, cross, length
