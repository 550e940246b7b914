"""An interruption (Ctrl-C, SIGTERM) waits out a write that must not stop halfway."""

from __future__ import annotations

import os
import signal

import pytest

from twin.interruption import deferred_interrupts, interruptible, interruption_reason


def _signalled_within(sig: int, depth: int, done: list[str]) -> None:
    """Within ``interruptible()`` and ``depth`` nested deferred blocks, send ``sig`` to
    this process, then note each block's end in ``done``."""
    with interruptible():
        if depth == 0:
            os.kill(os.getpid(), sig)
            for _ in range(1000):  # the handler runs at the next bytecode boundary
                pass
            done.append("no interruption came")
            return
        with deferred_interrupts():
            if depth == 2:
                with deferred_interrupts():
                    os.kill(os.getpid(), sig)
                done.append("inner block ended")
            else:
                os.kill(os.getpid(), sig)
                done.append("the rest of the block ran")
        done.append("not reached")


@pytest.mark.parametrize(
    ("sig", "message"), [(signal.SIGTERM, "stopped by SIGTERM"), (signal.SIGINT, "")]
)
def test_an_interruption_waits_for_the_end_of_a_deferred_block(sig, message):
    done: list[str] = []
    with pytest.raises(KeyboardInterrupt) as caught:
        _signalled_within(sig, 1, done)
    assert done == ["the rest of the block ran"]
    assert str(caught.value) == message


def test_outside_a_deferred_block_an_interruption_is_immediate():
    done: list[str] = []
    with pytest.raises(KeyboardInterrupt, match="stopped by SIGTERM"):
        _signalled_within(signal.SIGTERM, 0, done)
    assert done == []


def test_nested_blocks_raise_once_at_the_outermost_end():
    done: list[str] = []
    with pytest.raises(KeyboardInterrupt):
        _signalled_within(signal.SIGTERM, 2, done)
    assert done == ["inner block ended"]


@pytest.mark.parametrize(
    ("sig", "reason"), [(signal.SIGTERM, "stopped by SIGTERM"), (signal.SIGINT, "Ctrl-C")]
)
def test_the_reason_of_an_interruption_is_never_empty(sig, reason):
    with pytest.raises(KeyboardInterrupt) as caught:
        _signalled_within(sig, 0, [])
    assert interruption_reason(caught.value) == reason
    assert interruption_reason(KeyboardInterrupt()) == "Ctrl-C"
