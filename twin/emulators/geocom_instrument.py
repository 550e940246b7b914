"""The emulated GeoCOM instrument's state and its remote procedures: what each RPC does
to a wrapped :class:`twin.hal.TotalStation`, called only while holding the shared ``lock``.

Angles are radians: ``Hz`` clockwise, ``V`` the zenith angle
(:mod:`twin.drivers.geocom_codes` converts them). The RPCs answered:

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

Parameters that do not parse are answered ``IVPARAM`` (2); a failure the station does not
document, ``FATAL`` (4).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable

import numpy as np

from twin.drivers.geocom_codes import (
    geocom_from_polar,
    inclination_from_tilt,
    polar_from_geocom,
)
from twin.emulators.geocom_requests import (
    AUT_NO_TARGET,
    COM_PROC_UNAVAIL,
    COM_SRVR_RX_CHECKSUM_ERROR,
    EDM_DISTRANGE_ERR,
    FATAL,
    INSTRUMENT_TILT,
    IVPARAM,
    OK,
    SYSBUSY,
    TIME_OUT,
    TMC_DIST_ERROR,
    Request,
    format_reply,
)
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

TMC_STOP = 0
TMC_CLEAR = 3

FIRMWARE = (1, 0, 0)
"""What ``CSV_GetSWVersion`` reports (release, version, subversion)."""

GEOCOM_VERSION = (1, 50, 0)
"""What ``COM_GetSWVersion`` reports: the reference manual's GeoCOM release."""


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


class GeoComInstrument:
    """The state of a GeoCOM instrument played by a :class:`twin.hal.TotalStation`: where
    the telescope points, the shot kept, the precision of the values it answers.

    Args:
        station: the instrument that answers (the twin's, or any other).
        lock: held around every call of ``station`` (the world is shared).
        instrument_name: what ``CSV_GetInstrumentName`` answers (no quotes or line ends).
        serial_number: what ``CSV_GetInstrumentNo`` answers (decimal digits).

    Raises:
        ValueError: a name with quotes or line ends, a serial number that is not digits.
    """

    def __init__(
        self,
        station: TotalStation,
        lock: threading.RLock,
        *,
        instrument_name: str = "TS16 R500",
        serial_number: str = "1234567",
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
        self.precision = 15
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
