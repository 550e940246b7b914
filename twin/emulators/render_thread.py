"""Rendering for threads that do not own an OpenGL context.

An OpenGL (EGL, OSMesa) context is current in one thread only: the camera servers of the
emulators run in threads of their own, so one thread owns the world's
:class:`twin.sim.capture.CameraSimulator` and renders what any thread asks for.
"""

from __future__ import annotations

import queue
import threading
from concurrent.futures import Future

from twin.closing import Closing
from twin.sim.capture import CameraSimulator, Frame
from twin.sim.world import World

RENDER_TIMEOUT = 60.0
"""Longest wait for one frame, wall seconds (a render takes milliseconds)."""


class RenderThread(Closing):
    """A thread that makes a world's camera simulator and renders its cameras on request.

    It has the simulator's ``world`` and ``capture(camera)``, callable from any thread
    (the caller holds the world's lock while it waits, so nothing moves during a render).

    Args:
        world: the world. seed: the sensor noise's seed (default: the scenario's).

    Raises:
        twin.sim.gl.RenderBackendError: no rendering backend (from the constructor).
    """

    def __init__(self, world: World, seed: int | None = None) -> None:
        self.world = world
        self._requests: queue.Queue[tuple[str, Future[Frame]] | None] = queue.Queue()
        self._ready: Future[None] = Future()
        self._thread = threading.Thread(
            target=self._run, args=(seed,), name="camera-render", daemon=True
        )
        self._thread.start()
        self._ready.result(timeout=RENDER_TIMEOUT)
        self._closed = False

    def _run(self, seed: int | None) -> None:
        try:
            simulator = CameraSimulator(self.world, seed=seed)
        except BaseException as exc:
            self._ready.set_exception(exc)
            return
        self._ready.set_result(None)
        try:
            while (item := self._requests.get()) is not None:
                camera, done = item
                try:
                    done.set_result(simulator.capture(camera))
                except Exception as exc:
                    done.set_exception(exc)
        finally:
            simulator.close()

    def capture(self, camera: str) -> Frame:
        """One rendered frame of ``camera`` (the world as it is now)."""
        if self._closed:
            raise RuntimeError("the render thread is closed")
        done: Future[Frame] = Future()
        self._requests.put((camera, done))
        return done.result(timeout=RENDER_TIMEOUT)

    def close(self) -> None:
        """Stop the thread and release its context; twice is harmless."""
        if self._closed:
            return
        self._closed = True
        self._requests.put(None)
        self._thread.join(timeout=RENDER_TIMEOUT)
