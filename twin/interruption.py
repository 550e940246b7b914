"""Interruptions end a command the same way, whatever sends them.

Ctrl-C (SIGINT) raises :class:`KeyboardInterrupt` in Python; within :func:`interruptible`,
SIGTERM (what a service manager or a cluster's scheduler sends) and SIGHUP (a closed
terminal) raise it too. So one path serves them all: the ``finally`` blocks on the way out
close the run's log (a killed run's log reads back whole) and the rig's devices (closing a
simulated base stops it; a real robot's driver will stop its robot the same way), and
:func:`twin.cli.main` says what was interrupted and exits with :data:`EXIT_INTERRUPTED`.
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


def _raise_interrupt(signum: int, _frame: object) -> None:
    raise KeyboardInterrupt(f"stopped by {signal.Signals(signum).name}")


@contextmanager
def interruptible() -> Iterator[None]:
    """Within the block, :data:`SIGNALS` interrupt as Ctrl-C does (in the main thread; in
    another thread signals cannot be handled, and the block changes nothing)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.signal(s, _raise_interrupt) for s in SIGNALS}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
