"""Misbehaviour of the emulated GeoCOM instrument on purpose: the faults a test sets while
the emulator runs (a garbled, cut, refused, silent or dropped answer)."""

from __future__ import annotations

import enum
import threading
from dataclasses import dataclass, field

GARBAGE = b"\x8a\xf3#&\xff%R1P?\x00\xc3\r\n"
"""What :attr:`Fault.GARBAGE` answers: bytes that are not ASCII, ended by CR LF."""


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
