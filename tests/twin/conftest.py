"""Fixtures shared by the tests of the drivers and the emulators."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np
import pytest


@pytest.fixture
def serve() -> Iterator[Callable[..., object]]:
    """A factory of started MJPEG servers (``serve(frames, **options)``), all closed after
    the test."""
    from twin.emulators.camera import MjpegServer

    servers: list[MjpegServer] = []

    def start(frames: Callable[[], np.ndarray], **kwargs: object) -> MjpegServer:
        server = MjpegServer(frames, **kwargs)
        servers.append(server)
        return server.start()

    try:
        yield start
    finally:
        for server in servers:
            server.close()
