"""Typed failures of the total station and of the measurements built on it.

Every failure is an :class:`InstrumentError` carrying a :class:`FailureReason`, so a caller
can either catch the specific subclass or switch on ``error.reason``. A failure is never
turned into a silent wrong number. Two kinds:

- the instrument reports no number (out of range, no prism, blocked, tilted, no distance,
  busy, no answer in time, an error code of its own);
- the instrument reported numbers but they fail a chi-square consistency test
  (:class:`ConsistencyError`): the three cubes of a marker do not fit the assembly (a wrong
  prism locked, or the child moved between the shots), or the children measured after the
  parent moved do not fit their world positions (a child moved, or a wrong prism). The
  error's ``details`` hold ``chi2``, ``dof``, ``threshold`` and ``false_alarm_rate``; the
  caller can count it and measure again (re-aim).
"""

from __future__ import annotations

import enum
from typing import Any, ClassVar


class FailureReason(enum.Enum):
    """Why the instrument returned no measurement."""

    OUT_OF_RANGE = "out_of_range"
    NO_PRISM_IN_CONE = "no_prism_in_cone"
    LINE_OF_SIGHT_BLOCKED = "line_of_sight_blocked"
    TILT_OUT_OF_RANGE = "tilt_out_of_range"
    DISTANCE_FAILED = "distance_failed"
    INSTRUMENT_BUSY = "instrument_busy"
    INSTRUMENT_TIMEOUT = "instrument_timeout"
    INSTRUMENT_FAULT = "instrument_fault"
    INCONSISTENT_MARKER = "inconsistent_marker"
    INCONSISTENT_CHILDREN = "inconsistent_children"


class InstrumentError(RuntimeError):
    """The instrument could not measure. ``reason`` says why, ``details`` holds the numbers."""

    reason: ClassVar[FailureReason]

    def __init__(self, message: str, **details: Any) -> None:
        super().__init__(message)
        self.details: dict[str, Any] = details


class OutOfRangeError(InstrumentError):
    """The locked prism is closer than the minimum or farther than the maximum distance."""

    reason = FailureReason.OUT_OF_RANGE


class NoPrismInConeError(InstrumentError):
    """No prism lies within the automatic aim's search cone around the pointing direction."""

    reason = FailureReason.NO_PRISM_IN_CONE


class LineOfSightBlockedError(InstrumentError):
    """Prisms lie within the search cone but the line of sight to every one is blocked."""

    reason = FailureReason.LINE_OF_SIGHT_BLOCKED


class TiltOutOfRangeError(InstrumentError):
    """The instrument is tilted beyond the compensator's working range."""

    reason = FailureReason.TILT_OUT_OF_RANGE


class DistanceMeasurementError(InstrumentError):
    """The distance meter returned no distance (no return signal, a signal too weak or
    too strong, the beam interrupted). ``details`` may hold the device's ``code``."""

    reason = FailureReason.DISTANCE_FAILED


class InstrumentBusyError(InstrumentError):
    """The instrument refused the request because it is still doing another (a
    positioning, a measurement). Asking again later is safe."""

    reason = FailureReason.INSTRUMENT_BUSY


class InstrumentTimeoutError(InstrumentError):
    """The instrument did not finish (or did not answer) in the time allowed. Asking again
    is safe; a device that never answers again is lost
    (:class:`twin.hal.errors.DeviceLostError`)."""

    reason = FailureReason.INSTRUMENT_TIMEOUT


class InstrumentFaultError(InstrumentError):
    """The instrument answered with an error the driver does not map to one of the others
    (an unknown or fatal return code). ``details`` hold the device's ``code``; the message
    names it. Not retried."""

    reason = FailureReason.INSTRUMENT_FAULT


class ConsistencyError(InstrumentError):
    """Measurements fail their chi-square consistency test: no pose is returned from them.

    ``details`` hold ``chi2``, ``dof``, ``threshold`` and ``false_alarm_rate`` (the
    probability that consistent data raise this error).
    """


class InconsistentMarkerError(ConsistencyError):
    """The three cube shots of a child do not fit the marker assembly: a wrong prism was
    locked (e.g. cube 1 instead of cube 0 on a far child), or the child moved between shots."""

    reason = FailureReason.INCONSISTENT_MARKER


class InconsistentChildrenError(ConsistencyError):
    """The children measured from the parent's new station do not fit their world
    positions: a child moved between the two measurements, or a wrong prism was locked."""

    reason = FailureReason.INCONSISTENT_CHILDREN
