"""Interruptions end a command the same way, whatever sends them.

Ctrl-C (SIGINT) raises :class:`KeyboardInterrupt` in Python; within :func:`interruptible`,
SIGTERM (what a service manager or a cluster's scheduler sends) and SIGHUP (a closed
terminal) raise it too, and any of them waits out a :func:`deferred_interrupts` block (a log
record being written). So one path serves them all: the ``finally`` blocks on the way out
close the run's log (a killed run's log reads back whole) and the rig's devices (closing a
simulated base stops it; a real robot's driver will stop its robot the same way), and
:func:`twin.cli.main` says what was interrupted (:func:`interruption_reason`: why) and exits
with :data:`EXIT_INTERRUPTED`.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

EXIT_INTERRUPTED = 130
"""The exit code of an interrupted command (128 + SIGINT, as shells report Ctrl-C)."""

SIGNALS = tuple(s for s in (signal.SIGTERM, getattr(signal, "SIGHUP", None)) if s is not None)
"""Signals turned into :class:`KeyboardInterrupt` within :func:`interruptible`."""

_deferring = 0  # depth of deferred_interrupts() blocks (signals reach the main thread only)
_pending: int | None = None  # a signal that arrived within one


def interruption_reason(exc: BaseException) -> str:
    """Why a command was interrupted, for the line it prints (``interrupted (REASON)``):
    the interruption's message (``stopped by SIGTERM``), or ``Ctrl-C`` where it has none
    (Python's own KeyboardInterrupt); never empty."""
    return str(exc) or "Ctrl-C"


def _interrupt(signum: int) -> KeyboardInterrupt:
    # Ctrl-C keeps Python's own (empty) message: interruption_reason() says "Ctrl-C".
    if signum == signal.SIGINT:
        return KeyboardInterrupt()
    return KeyboardInterrupt(f"stopped by {signal.Signals(signum).name}")


def _raise_interrupt(signum: int, _frame: object) -> None:
    global _pending
    if _deferring:
        _pending = signum
        return
    raise _interrupt(signum)


@contextmanager
def interruptible() -> Iterator[None]:
    """Within the block, :data:`SIGNALS` interrupt as Ctrl-C does (in the main thread; in
    another thread signals cannot be handled, and the block changes nothing)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.signal(s, _raise_interrupt) for s in (signal.SIGINT, *SIGNALS)}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


@contextmanager
def deferred_interrupts() -> Iterator[None]:
    """Within the block, an interruption (within :func:`interruptible`) waits until the
    block ends, and is raised there: for writes that must not stop halfway, such as a
    record of the run's log (a record cut in two would make the log unreadable)."""
    global _deferring, _pending
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _deferring += 1
    try:
        yield
    finally:
        _deferring -= 1
        if _deferring == 0 and _pending is not None:
            signum, _pending = _pending, None
            raise _interrupt(signum)
