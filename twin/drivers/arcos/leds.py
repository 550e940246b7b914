"""A child's marker LEDs on the Pioneer's user digital outputs (ARCOS DIGOUT)."""

from __future__ import annotations

import contextlib
from collections.abc import Sequence

from twin.drivers.arcos.connection import PioneerConnection
from twin.drivers.arcos.protocol import Command
from twin.hal.devices import MarkerLeds
from twin.hal.errors import DeviceLostError
from twin.hal.readings import LedSwitch


class ArcosLeds(MarkerLeds):
    """LEDs switched by DIGOUT; :meth:`switch` returns once a SIP shows the new outputs,
    so that an image taken afterwards sees them as asked.

    Args:
        connection: the robot's open session (shared with its base, which closes it).
        child: the child's name.
        bits: ``bits[k]`` is the digital output (0-7) of LED k, lowest LED first.
    """

    def __init__(self, connection: PioneerConnection, *, child: str, bits: Sequence[int]) -> None:
        b = tuple(int(x) for x in bits)
        if not b or any(not 0 <= x <= 7 for x in b) or len(set(b)) != len(b):
            raise ValueError(f"bits must be distinct digital outputs 0-7, got {tuple(bits)}")
        self.connection = connection
        self._child = child
        self.bits = b
        self.mask = sum(1 << x for x in b)

    @property
    def child(self) -> str:
        return self._child

    @property
    def count(self) -> int:
        return len(self.bits)

    def _outputs(self, flags: Sequence[bool]) -> int:
        return sum(1 << x for x, f in zip(self.bits, flags, strict=True) if f)

    def switch(self, on: Sequence[bool]) -> LedSwitch:
        """Light the LEDs whose flag is True and switch off the others.

        Raises:
            ValueError: not one flag per LED.
            DeviceLostError: the link failed, or no SIP showed the outputs in time.
        """
        flags = tuple(bool(f) for f in on)
        if len(flags) != self.count:
            raise ValueError(f"give {self.count} flags (one per LED), got {len(flags)}")
        values = self._outputs(flags)
        conn = self.connection
        seen = conn.sip_count
        conn.send(Command.DIGOUT, (self.mask << 8) | values)
        conn.wait_for(lambda s: (s.digout & self.mask) == values, after=seen)
        return LedSwitch(self._child, conn.clock.now(), flags)

    def close(self) -> None:
        """Switch the LEDs off if the session is still open (without waiting)."""
        with contextlib.suppress(DeviceLostError):
            self.connection.send(Command.DIGOUT, self.mask << 8)
