"""A camera that serves MJPEG over HTTP on localhost, as IP cameras do.

``GET /stream.mjpg`` answers ``multipart/x-mixed-replace`` with one JPEG part per frame
(each part with its ``Content-Type`` and ``Content-Length``); ``GET /snapshot.jpg`` one
JPEG. OpenCV reads the stream with ``cv2.VideoCapture(server.url)`` (its FFmpeg backend),
so :class:`twin.drivers.camera.OpenCvCamera` is tested against it as against a real camera.

Each frame is made by calling ``frames()`` when it is due, so it shows the world (the LEDs)
as it is at that moment; every client gets its own frames at ``fps``.

Faults a test can inject: :attr:`MjpegServer.stalled` (frames stop, the connections stay
open, as a camera that hangs), :meth:`MjpegServer.drop` (every open connection is cut, as
a camera that reboots or a cable pulled; new connections are accepted).
"""

from __future__ import annotations

import contextlib
import http.server
import socket
import threading
import time
from collections.abc import Callable

import cv2
import numpy as np

from twin.closing import Closing

BOUNDARY = "frame"
"""The multipart boundary between the JPEG parts."""

DEFAULT_QUALITY = 95
"""JPEG quality of the frames. 95 (``benchmarks/bench_jpeg_centroids.py``, LED spots of
sigma 0.95 px, 200 DN peak on 2 DN of noise): every LED is found, the systematic centroid
shift the encoding adds is 0.005 px against 0.022 px of the detector's own noise on the
same spots, for 16 kB and 0.16 ms per 320 x 240 frame. At 90 one LED in a hundred is lost
and the shift is 0.013 px; at 75 and below most LEDs are lost (the encoding smooths the
noise away and the block artefacts make the spots look partial or ambiguous)."""


def encode_jpeg(image: np.ndarray, quality: int = DEFAULT_QUALITY) -> bytes:
    """A frame as JPEG bytes.

    Args:
        image: (H, W) uint8 gray or (H, W, 3) uint8 RGB.
        quality: JPEG quality, 1..100.

    Raises:
        ValueError: not an 8-bit gray or RGB image, or a quality outside 1..100.
    """
    a = np.asarray(image)
    if a.dtype != np.uint8 or not (a.ndim == 2 or (a.ndim == 3 and a.shape[2] == 3)):
        raise ValueError(f"a frame must be (H, W) or (H, W, 3) uint8, got {a.shape} {a.dtype}")
    if not 1 <= int(quality) <= 100:
        raise ValueError(f"JPEG quality must be 1..100, got {quality!r}")
    if a.ndim == 3:
        a = cv2.cvtColor(a, cv2.COLOR_RGB2BGR)
    ok, data = cv2.imencode(".jpg", a, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise ValueError(f"could not encode a {a.shape} frame as JPEG")
    return data.tobytes()


class _Server(http.server.ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, owner: MjpegServer, port: int) -> None:
        self.owner = owner
        super().__init__(("127.0.0.1", port), _Handler)


class _Handler(http.server.BaseHTTPRequestHandler):
    server: _Server
    protocol_version = "HTTP/1.0"

    def log_message(self, format: str, *args: object) -> None:
        """Quiet: a test's output is not the place for an access log."""

    def do_GET(self) -> None:
        owner = self.server.owner
        path = self.path.split("?", 1)[0]
        if path == "/stream.mjpg":
            owner._serve_stream(self)
        elif path == "/snapshot.jpg":
            owner._serve_snapshot(self)
        else:
            self.send_error(404, f"no {path}; try /stream.mjpg or /snapshot.jpg")


class MjpegServer(Closing):
    """An HTTP server on 127.0.0.1 that streams ``frames()`` as MJPEG.

    Args:
        frames: makes one frame, (H, W) uint8 gray or (H, W, 3) uint8 RGB; called from
            the server's threads (one per client) whenever a frame is due.
        fps: frames per second sent to each client.
        quality: JPEG quality, 1..100.
        port: TCP port; 0 picks a free one (see :attr:`url`).

    Attributes:
        stalled: while True no frame is sent (the connections stay open); a test sets it.
        frames_sent: frames sent so far, over all clients.
    """

    def __init__(
        self,
        frames: Callable[[], np.ndarray],
        *,
        fps: float = 30.0,
        quality: int = DEFAULT_QUALITY,
        port: int = 0,
    ) -> None:
        if not (np.isfinite(fps) and fps > 0):
            raise ValueError(f"fps must be a positive number, got {fps!r}")
        if not 1 <= int(quality) <= 100:
            raise ValueError(f"JPEG quality must be 1..100, got {quality!r}")
        self._frames = frames
        self.fps = float(fps)
        self.quality = int(quality)
        self.stalled = False
        self.frames_sent = 0
        self._server = _Server(self, int(port))
        self._thread: threading.Thread | None = None
        self._closed = threading.Event()
        self._lock = threading.Lock()
        self._connections: set[socket.socket] = set()

    @property
    def port(self) -> int:
        """The TCP port the server listens on."""
        return int(self._server.server_address[1])

    @property
    def url(self) -> str:
        """The stream's address, ``http://127.0.0.1:PORT/stream.mjpg``."""
        return f"http://127.0.0.1:{self.port}/stream.mjpg"

    @property
    def snapshot_url(self) -> str:
        """One frame's address, ``http://127.0.0.1:PORT/snapshot.jpg``."""
        return f"http://127.0.0.1:{self.port}/snapshot.jpg"

    def start(self) -> MjpegServer:
        """Start serving in a background thread (once); returns the server."""
        if self._closed.is_set():
            raise RuntimeError("the MJPEG server is closed")
        if self._thread is None:
            self._thread = threading.Thread(
                target=self._server.serve_forever,
                kwargs={"poll_interval": 0.05},
                name=f"mjpeg-{self.port}",
                daemon=True,
            )
            self._thread.start()
        return self

    def drop(self) -> None:
        """Cut every open connection (the clients see their stream end); new ones are
        accepted."""
        with self._lock:
            connections = list(self._connections)
            self._connections.clear()
        for sock in connections:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)

    def close(self) -> None:
        """Stop serving, cut the connections and free the port. Twice is harmless."""
        if self._closed.is_set():
            return
        self._closed.set()
        self.drop()
        if self._thread is not None:
            self._server.shutdown()
            self._thread.join(timeout=5.0)
        self._server.server_close()

    # -- serving, in the server's threads -----------------------------------------------
    def _frame(self) -> bytes:
        return encode_jpeg(self._frames(), self.quality)

    def _serve_snapshot(self, handler: _Handler) -> None:
        data = self._frame()
        handler.send_response(200)
        handler.send_header("Content-Type", "image/jpeg")
        handler.send_header("Content-Length", str(len(data)))
        handler.send_header("Cache-Control", "no-cache")
        handler.end_headers()
        handler.wfile.write(data)

    def _serve_stream(self, handler: _Handler) -> None:
        sock = handler.connection
        with self._lock:
            self._connections.add(sock)
        try:
            handler.send_response(200)
            handler.send_header("Content-Type", f"multipart/x-mixed-replace; boundary={BOUNDARY}")
            handler.send_header("Cache-Control", "no-cache")
            handler.send_header("Pragma", "no-cache")
            handler.end_headers()
            period = 1.0 / self.fps
            due = time.monotonic()
            while not self._closed.is_set():
                with self._lock:
                    if sock not in self._connections:
                        return
                now = time.monotonic()
                if now < due:
                    self._closed.wait(due - now)
                    continue
                due = max(due + period, now)
                if self.stalled:
                    continue
                data = self._frame()
                head = (
                    f"--{BOUNDARY}\r\nContent-Type: image/jpeg\r\n"
                    f"Content-Length: {len(data)}\r\n\r\n"
                ).encode("ascii")
                handler.wfile.write(head + data + b"\r\n")
                handler.wfile.flush()
                self.frames_sent += 1
        except OSError:
            return  # the client went away, or the connection was dropped
        finally:
            with self._lock:
                self._connections.discard(sock)
