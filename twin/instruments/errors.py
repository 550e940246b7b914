"""Typed failures of the total station: the instrument reports no number, and says why.

Every failure is an :class:`InstrumentError` carrying a :class:`FailureReason`, so a caller
can either catch the specific subclass or switch on ``error.reason``. A failure is never
turned into a silent wrong number.
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
