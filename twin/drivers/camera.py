"""Real cameras behind :class:`twin.hal.Camera`: anything OpenCV opens (GenICam cameras
are in :mod:`twin.drivers.genicam`).

:meth:`Camera.capture` must return an image whose exposure began after the call: the LEDs
were switched just before it. For a live source (a device, an RTSP or HTTP stream) a reader
thread takes every frame as it arrives, and :meth:`OpenCvCamera.capture` returns the
``settle_frames + 1``-th frame that arrives after the call; the frames before it (the one
being exposed or in flight when the LEDs switched) are dropped.

Timeouts are in rig seconds (:class:`twin.drivers.clock.WallClock`): an emulated world that
runs faster than real time shortens them by its time scale.

A stream that ends is reopened for ``timeout_s`` before the camera is given up as lost (one
:class:`DeviceLostError` naming the camera and its source). OpenCV and FFmpeg would print a
warning or two at every attempt ("Connection refused", "can't be used to capture by name"):
their own logging is silenced where the driver opens a stream (:func:`quiet_video_logs`),
unless the user set ``OPENCV_LOG_LEVEL`` or ``OPENCV_FFMPEG_LOGLEVEL`` to see it.
"""

from __future__ import annotations

import collections
import os
import re
import threading
import time

import cv2
import numpy as np
from numpy.typing import NDArray

from twin.drivers.clock import WallClock
from twin.hal.devices import Camera
from twin.hal.errors import DeviceLostError, NoFrameError
from twin.hal.readings import CameraImage

STREAM_SCHEMES = ("rtsp://", "rtsps://", "http://", "https://", "udp://", "tcp://", "rtmp://")
"""Sources that are network streams (opened with OpenCV's FFmpeg backend)."""

READ_TIMEOUT_FACTOR = 2.0
"""A stream's read gives up after this many times the camera's timeout: a stall shorter
than that is waited out (captures meanwhile end with NoFrameError), a longer one makes the
reader reopen the stream."""

RETRY_INTERVAL = 0.1
"""Wall seconds between attempts to reopen a stream."""

DRAIN_GAP = 0.003
"""A read of a live source that takes this much (wall s) longer than twice the quickest
read before it waited for a new frame: what the source had buffered is drained."""

MAX_DRAIN = 100
"""Most frames dropped while draining a live source after opening it."""

CLOSE_WAIT = 1.0
"""Wall seconds :meth:`OpenCvCamera.close` waits for the reader beyond a read's timeout."""

FFMPEG_QUIET = "-8"
"""FFmpeg's log level ``AV_LOG_QUIET``, for ``OPENCV_FFMPEG_LOGLEVEL``."""


def quiet_video_logs() -> None:
    """Silence OpenCV's and FFmpeg's own logging (the warnings a lost or refused stream
    gives at every read and reopening; the driver reports the loss itself), unless the
    user asked for it through ``OPENCV_LOG_LEVEL`` or ``OPENCV_FFMPEG_LOGLEVEL``.

    FFmpeg's level is read once, when OpenCV first uses FFmpeg in the process: call this
    before opening a stream.
    """
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", FFMPEG_QUIET)
    if "OPENCV_LOG_LEVEL" not in os.environ:
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)


def opencv_link(source: int | str) -> str:
    """An OpenCV camera's link as :class:`DeviceLostError` names it."""
    return f"{source} (OpenCV)"


def _is_stream(source: int | str) -> bool:
    return isinstance(source, str) and source.lower().startswith(STREAM_SCHEMES)


def _is_live(source: int | str) -> bool:
    return isinstance(source, int) or _is_stream(source) or str(source).startswith("/dev/")


def _open_sequence(pattern: str) -> cv2.VideoCapture:
    """An image sequence (``frames/%04d.png``) from its lowest-numbered file: OpenCV by
    itself finds only sequences that start at 0..4."""
    cap = cv2.VideoCapture(pattern, cv2.CAP_IMAGES)
    if cap.isOpened():
        return cap
    folder, name = os.path.split(pattern)
    parts = re.split(r"%0?\d*d", name)
    if len(parts) != 2:
        return cap
    match = re.compile(re.escape(parts[0]) + r"(\d+)" + re.escape(parts[1]) + "$")
    try:
        numbers = [int(m.group(1)) for f in os.listdir(folder or ".") if (m := match.match(f))]
    except OSError:
        return cap
    if not numbers:
        return cap
    cap.release()
    return cv2.VideoCapture(pattern % min(numbers), cv2.CAP_IMAGES)


def check_timeout(timeout_s: float) -> float:
    """``timeout_s`` as a float, checked: a positive number of seconds.

    Raises:
        ValueError: anything else.
    """
    if not (np.isfinite(timeout_s) and timeout_s > 0):
        raise ValueError(f"timeout_s must be a positive number of seconds, got {timeout_s!r}")
    return float(timeout_s)


def _check_size(name: str, image_size: tuple[int, int] | None) -> tuple[int, int] | None:
    if image_size is None:
        return None
    size = tuple(int(v) for v in image_size)
    if len(size) != 2 or min(size) < 1:
        raise ValueError(f"{name}: image_size must be (width, height) px, got {image_size!r}")
    return (size[0], size[1])


class OpenCvCamera(Camera):
    """A camera read through ``cv2.VideoCapture``.

    Args:
        source: a device index, a V4L2 path (``/dev/video0``), an RTSP or HTTP (MJPEG) URL,
            a video file, or an image sequence in OpenCV's printf pattern
            (``frames/%04d.png``).
        name: the camera's name in the rig.
        clock: the rig's clock (timestamps; timeouts are rig seconds).
        image_size: expected (width, height), px, checked against the first frame (and
            asked of a device before it); None: the source's.
        settle_frames: frames of a live source dropped after the call before the one
            returned (1: the frame being exposed when the LEDs switched).
        timeout_s: time a capture waits for its frame, and a stream's opening, rig s.
        grayscale: deliver (H, W) uint8 frames; else (H, W, 3) uint8 RGB.

    Raises:
        twin.hal.errors.DeviceLostError: the source cannot be opened or gives no first
            frame.
        ValueError: ``image_size`` differs from the source's frames (or a bad argument).
    """

    def __init__(
        self,
        source: int | str,
        *,
        name: str,
        clock: WallClock,
        image_size: tuple[int, int] | None = None,
        settle_frames: int = 1,
        timeout_s: float = 5.0,
        grayscale: bool = True,
    ) -> None:
        if isinstance(source, bool) or not isinstance(source, int | str | os.PathLike):
            raise ValueError(f"{name}: source must be a device index or a path/URL, got {source!r}")
        if not (isinstance(settle_frames, int) and settle_frames >= 0):
            raise ValueError(
                f"{name}: settle_frames must be an integer >= 0, got {settle_frames!r}"
            )
        self._source: int | str = source if isinstance(source, int) else os.fspath(source)
        self._name = name
        self.clock = clock
        self.settle_frames = settle_frames
        self.timeout_s = check_timeout(timeout_s)
        self.grayscale = bool(grayscale)
        self.live = _is_live(self._source)
        self.link = opencv_link(self._source)
        """Where and how the camera is reached, for messages: ``SOURCE (OpenCV)``."""
        wanted = _check_size(name, image_size)
        self._cond = threading.Condition()
        self._frames: collections.deque[tuple[int, float, NDArray]] = collections.deque(
            maxlen=settle_frames + 8
        )
        self._count = 0
        self._lost: str | None = None
        self._stop = threading.Event()
        self._closed = False
        self._thread: threading.Thread | None = None
        self._pending: NDArray | None = None

        cap = self._open(wanted)
        if cap is None:
            raise DeviceLostError(name, "cannot open the source", link=self.link)
        ok, first = cap.read()
        if not ok or first is None:
            cap.release()
            raise DeviceLostError(name, "the source gave no first frame", link=self.link)
        h, w = first.shape[:2]
        self._size = (int(w), int(h))
        if wanted is not None and wanted != self._size:
            cap.release()
            raise ValueError(
                f"{name}: image_size {wanted} (width, height) does not match the frames of "
                f"{self._source!r}, which are {self._size}"
            )
        self._identity: dict[str, object] = {
            "source": self._source,
            "resolution": self._size,
            "fps": fps if (fps := float(cap.get(cv2.CAP_PROP_FPS))) > 0 else None,
            "backend": cap.getBackendName(),
            "live": self.live,
        }
        self._cap: cv2.VideoCapture | None = cap
        if self.live and not self._drain(cap):
            cap.release()
            raise DeviceLostError(name, "the source stopped after one frame", link=self.link)
        if self.live:
            self._thread = threading.Thread(
                target=self._read_stream, name=f"camera-{name}", daemon=True
            )
            self._thread.start()
        else:
            self._pending = first

    # -- the hal interface ---------------------------------------------------------------
    @property
    def name(self) -> str:
        return self._name

    @property
    def image_size(self) -> tuple[int, int]:
        return self._size

    def identify(self) -> dict[str, object]:
        """What the source is: ``resolution`` (w, h) px, ``fps`` (as the backend reports
        it, None when it does not know; FFmpeg reports 25 for MJPEG over HTTP whatever the
        camera sends), ``backend`` (OpenCV's name for it), ``source``,
        ``live`` (a stream or device rather than a file)."""
        return dict(self._identity)

    def capture(self) -> CameraImage:
        """The next frame of a file; of a live source the ``settle_frames + 1``-th that
        arrives after the call.

        Raises:
            twin.hal.errors.NoFrameError: no such frame within ``timeout_s`` (a stalled
                stream), or the file has ended.
            twin.hal.errors.DeviceLostError: the stream ended and could not be reopened,
                or the camera is closed.
        """
        if self._closed:
            raise DeviceLostError(
                self._name, "the camera is closed", link=self.link, source=self._source
            )
        if not self.live:
            return self._next_file_frame()
        wait = self.clock.wall(self.timeout_s)
        deadline = time.monotonic() + wait
        with self._cond:
            target = self._count + self.settle_frames + 1
            while self._count < target:
                if self._lost is not None:
                    raise DeviceLostError(
                        self._name, self._lost, link=self.link, source=self._source
                    )
                left = deadline - time.monotonic()
                if left <= 0:
                    raise NoFrameError(
                        self._name,
                        f"no frame within {self.timeout_s} s from {self._source!r}",
                        timeout_s=self.timeout_s,
                        source=self._source,
                    )
                self._cond.wait(left)
            stamp, frame = next((t, f) for k, t, f in self._frames if k >= target)
        return CameraImage(self._name, stamp, self._convert(frame))

    def close(self) -> None:
        """Stop the reader and release the source. Twice is harmless."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        if self._thread is not None:
            self._thread.join(READ_TIMEOUT_FACTOR * self.clock.wall(self.timeout_s) + CLOSE_WAIT)
        elif self._cap is not None:
            self._cap.release()
        self._cap = None
        with self._cond:
            self._cond.notify_all()

    # -- opening and reading -------------------------------------------------------------
    def _open(self, wanted: tuple[int, int] | None = None) -> cv2.VideoCapture | None:
        source = self._source
        if _is_stream(source):
            quiet_video_logs()
            ms = max(int(1000 * self.clock.wall(self.timeout_s)), 1)
            cap = cv2.VideoCapture(
                source,
                cv2.CAP_FFMPEG,
                [
                    cv2.CAP_PROP_OPEN_TIMEOUT_MSEC,
                    ms,
                    cv2.CAP_PROP_READ_TIMEOUT_MSEC,
                    int(READ_TIMEOUT_FACTOR * ms),
                ],
            )
        elif isinstance(source, str) and "%" in source:
            cap = _open_sequence(source)
        else:
            cap = cv2.VideoCapture(source)
        if not cap.isOpened():
            cap.release()
            return None
        if self.live and not _is_stream(source):
            # A device: keep the driver's queue short, and ask for the expected size.
            cap.set(cv2.CAP_PROP_BUFFERSIZE, 1)
            if wanted is not None:
                cap.set(cv2.CAP_PROP_FRAME_WIDTH, wanted[0])
                cap.set(cv2.CAP_PROP_FRAME_HEIGHT, wanted[1])
        return cap

    def _next_file_frame(self) -> CameraImage:
        if self._pending is not None:
            frame, self._pending = self._pending, None
        else:
            assert self._cap is not None
            ok, frame = self._cap.read()
            if not ok or frame is None:
                raise NoFrameError(self._name, f"{self._source!r} has no more frames")
        return CameraImage(self._name, self.clock.now(), self._convert(frame))

    def _convert(self, frame: NDArray) -> NDArray[np.uint8]:
        if frame.dtype != np.uint8:
            frame = cv2.convertScaleAbs(frame, alpha=255.0 / max(float(frame.max()), 1.0))
        if frame.shape[:2] != (self._size[1], self._size[0]):
            raise NoFrameError(
                self._name,
                f"a frame of {frame.shape[1]} x {frame.shape[0]} px from {self._source!r}, "
                f"expected {self._size[0]} x {self._size[1]}",
            )
        if frame.ndim == 2:
            return frame if self.grayscale else cv2.cvtColor(frame, cv2.COLOR_GRAY2RGB)
        if frame.shape[2] == 4:
            frame = cv2.cvtColor(frame, cv2.COLOR_BGRA2BGR)
        if self.grayscale:
            return cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        return cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)

    def _reopen(self) -> cv2.VideoCapture | None:
        """Open the stream again, trying for ``timeout_s``; None when it cannot be."""
        deadline = time.monotonic() + self.clock.wall(self.timeout_s)
        while not self._stop.is_set():
            cap = self._open()
            if cap is not None:
                return cap
            if time.monotonic() >= deadline:
                return None
            self._stop.wait(RETRY_INTERVAL)
        return None

    def _drain(self, cap: cv2.VideoCapture) -> bool:
        """Drop the frames a live source buffered while it was opened (FFmpeg reads a few
        to learn the stream's format; a device queues some): read until a read has to
        wait for its frame. False when the source failed meanwhile."""
        fastest = float("inf")
        deadline = time.monotonic() + self.clock.wall(self.timeout_s)
        for _ in range(MAX_DRAIN):
            t0 = time.monotonic()
            if not cap.grab():
                return False
            took = time.monotonic() - t0
            if took > 2.0 * fastest + DRAIN_GAP or time.monotonic() > deadline:
                return True
            fastest = min(fastest, took)
        return True

    def _read_stream(self) -> None:
        """The reader thread: every frame as it arrives; a stream that ends is reopened."""
        cap = self._cap
        try:
            while not self._stop.is_set():
                ok, frame = cap.read() if cap is not None else (False, None)
                if self._stop.is_set():
                    break
                if ok and frame is not None:
                    stamp = self.clock.now()
                    with self._cond:
                        self._count += 1
                        self._frames.append((self._count, stamp, frame))
                        self._cond.notify_all()
                    continue
                if cap is not None:
                    cap.release()
                cap = self._reopen()
                while cap is not None and not self._drain(cap):
                    cap.release()
                    cap = self._reopen()
                if cap is None:
                    if not self._stop.is_set():
                        with self._cond:
                            self._lost = (
                                "connection lost: the stream ended and could not be reopened "
                                f"within {self.timeout_s} s"
                            )
                            self._cond.notify_all()
                    return
        finally:
            if cap is not None:
                cap.release()
