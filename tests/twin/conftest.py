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


@pytest.fixture(autouse=True, scope="session")
def _site_tables_in_a_temporary_cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """The site tables of the ``stands`` planner go to a temporary cache folder, never to
    the user's (the tests that read the variable set their own)."""
    import os

    from twin.envs.stand_cache import CACHE_ENV
    from twin.envs.stand_tables import clear_sites

    saved = os.environ.get(CACHE_ENV)
    os.environ[CACHE_ENV] = str(tmp_path_factory.mktemp("cache"))
    try:
        yield
    finally:
        clear_sites()  # saved now, into the temporary folder, not when the process ends
        if saved is None:
            os.environ.pop(CACHE_ENV, None)
        else:
            os.environ[CACHE_ENV] = saved
