"""The wall clock, optionally running faster than real time against emulated devices."""

from __future__ import annotations

import math
import time

from twin.hal.devices import Clock


class WallClock(Clock):
    """Seconds since the rig started, on the host's monotonic clock.

    Args:
        time_scale: rig seconds per wall second. 1 for real hardware; an emulated world
            may run faster (the rig file's ``time_scale``), and every timeout and period
            the drivers keep is in rig seconds, so they follow it.
    """

    def __init__(self, time_scale: float = 1.0) -> None:
        if not (math.isfinite(time_scale) and time_scale > 0):
            raise ValueError(f"time_scale must be a positive number, got {time_scale!r}")
        self.time_scale = float(time_scale)
        self._start = time.monotonic()

    def now(self) -> float:
        return (time.monotonic() - self._start) * self.time_scale

    def wall(self, seconds: float) -> float:
        """Wall seconds that ``seconds`` of rig time take."""
        return float(seconds) / self.time_scale

    def sleep(self, seconds: float) -> None:
        if not seconds >= 0:
            raise ValueError(f"cannot sleep a negative time, got {seconds} s")
        time.sleep(self.wall(seconds))
