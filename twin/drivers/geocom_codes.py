"""Pure parts of the Leica GeoCOM total-station protocol: angle conventions and return codes.

Angles (the one place they are converted):

- GeoCOM reports the horizontal angle ``Hz`` clockwise seen from above, in [0, 2pi) rad,
  and the vertical angle ``V`` as a zenith angle (0 up, pi/2 horizontal; in face II it lies
  in (pi, 2pi) and ``Hz`` is turned by pi). With the compensator on, both are levelled.
- The project's :class:`twin.instruments.polar.TotalStationMeasurement` counts its
  horizontal angle counter-clockwise from the levelled x-axis (``atan2(y, x)``) and its
  zenith angle in [0, pi]. The instrument's ``Hz = 0`` direction is the levelled x-axis.

So a prism on the +y axis has the project's horizontal angle pi/2 and GeoCOM's ``Hz``
3pi/2: :func:`geocom_from_polar` and :func:`polar_from_geocom` are the pair.

Inclination (the instrument's two-axis compensator, ``TMC_INCLINE`` of ``TMC_GetAngle1``):
the sensor turns with the alidade, so its two readings refer to the telescope's current
direction ``Hz``. The convention used here (not checked on hardware):

- ``length`` (``dLengthIncline``): the rise of the line of sight, rad: positive when a
  telescope levelled in the instrument frame points upwards in the levelled frame;
- ``cross`` (``dCrossIncline``): the rise of the trunnion axis's end on the left of the
  line of sight (looking through the eyepiece), rad.

With the project's tilt (roll, pitch), ``R_instrument2level = Ry(pitch) @ Rx(roll)``
(:mod:`twin.instruments.tilt`) and ``a = -Hz`` the counter-clockwise direction of the line
of sight: ``sin(length) = -sin(pitch) cos(a) + cos(pitch) sin(roll) sin(a)`` and
``sin(cross) = sin(pitch) sin(a) + cos(pitch) sin(roll) cos(a)``. For the telescope along
+x (``Hz = 0``) that is ``length = -pitch`` and ``cross = roll``.
:func:`inclination_from_tilt` and :func:`tilt_from_inclination` are the pair.

Return codes: every non-zero GeoCOM return code maps to one of the project's typed errors
(:func:`error_for_code`); the tables below say which. The numbers and names are those of
Leica's "TPS1200+/TS30/TM30 GeoCOM Reference Manual" (version 1.50), as
:class:`geocompy.geo.gctypes.GeoComCode` spells them.
"""

from __future__ import annotations

import math

from geocompy.geo.gctypes import GeoComCode

from twin.instruments.errors import (
    DistanceMeasurementError,
    InstrumentBusyError,
    InstrumentError,
    InstrumentFaultError,
    InstrumentTimeoutError,
    NoPrismInConeError,
    OutOfRangeError,
    TiltOutOfRangeError,
)

TWO_PI = 2.0 * math.pi


def _wrap(angle: float) -> float:
    """``angle`` rad wrapped into [0, 2pi)."""
    wrapped = math.fmod(angle, TWO_PI)
    if wrapped < 0.0:
        wrapped += TWO_PI
    return 0.0 if wrapped >= TWO_PI else wrapped


def _check_finite(**values: float) -> None:
    for name, value in values.items():
        if not math.isfinite(value):
            raise ValueError(f"{name} must be a finite angle in rad, got {value!r}")


def geocom_from_polar(horizontal: float, zenith: float) -> tuple[float, float]:
    """The project's levelled angles -> GeoCOM's face-I angles.

    Args:
        horizontal: counter-clockwise from the levelled x-axis, rad.
        zenith: zenith angle, rad in [0, pi].

    Returns:
        ``(hz, v)``: GeoCOM's clockwise horizontal angle in [0, 2pi) and zenith angle, rad.

    Raises:
        ValueError: an angle is not finite, or ``zenith`` lies outside [0, pi].
    """
    _check_finite(horizontal=horizontal, zenith=zenith)
    if not 0.0 <= zenith <= math.pi:
        raise ValueError(f"zenith must lie in [0, pi] rad, got {zenith!r}")
    return _wrap(-horizontal), float(zenith)


def polar_from_geocom(hz: float, v: float) -> tuple[float, float]:
    """GeoCOM's angles (either face) -> the project's levelled angles.

    Args:
        hz: GeoCOM's clockwise horizontal angle, rad (any turn).
        v: GeoCOM's vertical (zenith) angle, rad; in (pi, 2pi) for face II.

    Returns:
        ``(horizontal, zenith)``: counter-clockwise angle in [0, 2pi) and zenith angle in
        [0, pi], rad.

    Raises:
        ValueError: an angle is not finite.
    """
    _check_finite(hz=hz, v=v)
    v = _wrap(v)
    if v > math.pi:  # face II: the telescope looks the other way over the zenith
        return _wrap(-(hz - math.pi)), TWO_PI - v
    return _wrap(-hz), v


def inclination_from_tilt(roll: float, pitch: float, hz: float) -> tuple[float, float]:
    """The project's tilt -> GeoCOM's compensator readings with the telescope at ``hz``.

    Args:
        roll, pitch: tilt of the instrument, rad (:class:`twin.instruments.tilt.TiltReading`).
        hz: GeoCOM's clockwise horizontal angle of the telescope, rad.

    Returns:
        ``(cross, length)``: ``dCrossIncline`` and ``dLengthIncline``, rad (see the module).
    """
    _check_finite(roll=roll, pitch=pitch, hz=hz)
    a = -hz
    sr, sp, cp = math.sin(roll), math.sin(pitch), math.cos(pitch)
    length = math.asin(_clip(-sp * math.cos(a) + cp * sr * math.sin(a)))
    cross = math.asin(_clip(sp * math.sin(a) + cp * sr * math.cos(a)))
    return cross, length


def tilt_from_inclination(cross: float, length: float, hz: float) -> tuple[float, float]:
    """GeoCOM's compensator readings with the telescope at ``hz`` -> the project's tilt.

    Args:
        cross, length: ``dCrossIncline`` and ``dLengthIncline``, rad (see the module).
        hz: GeoCOM's clockwise horizontal angle of the telescope, rad.

    Returns:
        ``(roll, pitch)``, rad, as :class:`twin.instruments.tilt.TiltReading` defines them.
    """
    _check_finite(cross=cross, length=length, hz=hz)
    a = -hz
    sc, sl = math.sin(cross), math.sin(length)
    sp = _clip(sc * math.sin(a) - sl * math.cos(a))
    pitch = math.asin(sp)
    roll = math.asin(_clip((sc * math.cos(a) + sl * math.sin(a)) / math.cos(pitch)))
    return roll, pitch


def _clip(x: float) -> float:
    return min(1.0, max(-1.0, x))


def _codes(*members: GeoComCode) -> frozenset[int]:
    return frozenset(int(m) for m in members)


_C = GeoComCode

NO_TARGET_CODES = _codes(
    _C.AUT_DEV_ERROR,
    _C.AUT_NO_TARGET,
    _C.AUT_MULTIPLE_TARGETS,
    _C.AUT_BAD_ENVIRONMENT,
    _C.AUT_DETECTOR_ERROR,
    _C.ATA_SEVERAL_TARGETS,
    _C.ATA_BIG_SPOT,
    _C.ATA_BACKGROUND,
    _C.ATA_NO_TARGETS,
    _C.ATA_SPOT_ON_EDGE,
    _C.ATA_STRANGE_LIGHT,
    _C.ATA_HZ_FAIL,
    _C.ATA_V_FAIL,
    _C.ATA_HZ_STRANGE_L,
    _C.ATA_V_STRANGE_L,
    _C.CAM_NO_TARGET,
    _C.CAM_TARGET_NOT_FOUND,
)
"""The automatic aim (ATR) found no prism, or none it could lock on:
:class:`NoPrismInConeError`."""

DISTANCE_CODES = _codes(
    _C.TMC_ANGLE_OK,
    _C.TMC_ANGLE_NO_FULL_CORRECTION,
    _C.TMC_ANGLE_ACCURACY_GUARANTEE,
    _C.TMC_DIST_ERROR,
    _C.TMC_SIGNAL_ERROR,
    _C.EDM_NOSIGNAL,
    _C.EDM_TIMEOUT,
    _C.EDM_FLUKT_ERR,
    _C.EDM_NOT_FOUND,
    _C.EDM_SIGNTONOISE_ERR,
    _C.EDM_NOISEHIGH_ERR,
    _C.EDM_MULTRG_ERR,
    _C.EDM_NOPRECISE,
    _C.EDM_NOT_EXECUTED,
    _C.EDM_SIG_FORM_ERR,
)
"""The distance meter gave no distance (only angles are valid, no signal, too weak,
turbulence): :class:`DistanceMeasurementError`. ``TMC_NO_FULL_CORRECTION`` (1283) and
``TMC_ACCURACY_GUARANTEE`` (1284) are warnings that come with a valid distance, not here."""

OUT_OF_RANGE_CODES = _codes(
    _C.EDM_MEAS_DIST_NOT_ALLOWED, _C.EDM_DISTRANGE_ERR, _C.EDM_DIST_TOO_SHORT
)
"""The distance lies outside the distance meter's range: :class:`OutOfRangeError`."""

BUSY_CODES = _codes(
    _C.SYSBUSY, _C.EDM_BUSY, _C.TMC_BUSY, _C.MOT_BUSY, _C.COM_CONS_REQ, _C.COM_SRVR_IS_SLEEPING
)
"""The instrument is still doing something else: :class:`InstrumentBusyError`."""

TIMEOUT_CODES = _codes(
    _C.TIME_OUT,
    _C.ANG_TIME_OUT,
    _C.MOT_TIMEOUT,
    _C.MOT_HZ_TIMEOUT,
    _C.MOT_V_TIMEOUT,
    _C.COM_TIMEDOUT,
    _C.AUT_TIMEOUT,
)
"""The instrument did not finish in its own time: :class:`InstrumentTimeoutError`."""

TILT_CODES = _codes(_C.INSTRUMENT_TILT, _C.ANG_INCL_ERROR, _C.TMC_ANGLE_ERROR)
"""The compensator cannot level (tilted beyond its range, no valid inclination):
:class:`TiltOutOfRangeError`. ``TMC_ANGLE_ERROR`` (1290) is the instrument's "no valid
angle, check the inclination" and is read as a tilt beyond the compensator's range."""

DISTANCE_WARNINGS = _codes(_C.TMC_NO_FULL_CORRECTION, _C.TMC_ACCURACY_GUARANTEE)
"""Return codes of a measurement whose values (distance included) are still valid."""

ANGLE_WARNINGS = DISTANCE_WARNINGS | _codes(
    _C.TMC_ANGLE_OK, _C.TMC_ANGLE_NO_FULL_CORRECTION, _C.TMC_ANGLE_ACCURACY_GUARANTEE
)
"""Return codes of an angle reading whose angle values are still valid."""

DECODE_CODES = _codes(_C.COM_CANT_DECODE, _C.COM_TR_ID_MISMATCH, _C.COM_CLNT_RX_CHECKSUM_ERROR)
"""Codes the GeoCOM client itself gives to a reply it could not read (garbage, a reply to
another request, a wrong checksum), not the instrument."""

_TABLE: tuple[tuple[frozenset[int], type[InstrumentError]], ...] = (
    (NO_TARGET_CODES, NoPrismInConeError),
    (DISTANCE_CODES, DistanceMeasurementError),
    (OUT_OF_RANGE_CODES, OutOfRangeError),
    (BUSY_CODES, InstrumentBusyError),
    (TIMEOUT_CODES, InstrumentTimeoutError),
    (TILT_CODES, TiltOutOfRangeError),
)


def code_name(code: int) -> str:
    """GeoCOM's name of a return code (``GRC_`` prefix left out), or ``"unknown code"``."""
    try:
        return GeoComCode(code).name
    except ValueError:
        return "unknown code"


def error_class(code: int) -> type[InstrumentError]:
    """The project's error for a non-zero GeoCOM return code; an unknown code is a fault."""
    for codes, cls in _TABLE:
        if code in codes:
            return cls
    return InstrumentFaultError


def error_for_code(code: int, request: str, **details: object) -> InstrumentError:
    """The typed error for a non-zero return ``code`` that ``request`` (an RPC's name) got.

    The message names the request, the code and its GeoCOM name; ``details`` hold
    ``code``, ``name`` and ``request`` beside the given ones.
    """
    name = code_name(code)
    return error_class(code)(
        f"{request}: the instrument answered GeoCOM return code {code} ({name})",
        code=code,
        name=name,
        request=request,
        **details,
    )
