"""The OpenCV camera driver against the MJPEG emulator on localhost, image sequences and
video files in a temporary folder."""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable, Iterator

import cv2
import numpy as np
import pytest

from twin.drivers.camera import FFMPEG_QUIET, OpenCvCamera, quiet_video_logs
from twin.drivers.clock import WallClock
from twin.hal.errors import DeviceLostError, NoFrameError

W, H = 160, 120
JPEG_DN = 3  # a flat grey survives JPEG at quality 95 to within a few DN


def level(k: int) -> int:
    """The grey level that codes counter ``k`` (steps of 8 DN, far above JPEG's error)."""
    return 16 + 8 * (k % 28)


class Counter:
    """Frames of a flat grey that codes a counter the test changes; counts the frames made."""

    def __init__(self) -> None:
        self.k = 0
        self.made = 0
        self.lock = threading.Lock()

    def __call__(self) -> np.ndarray:
        with self.lock:
            self.made += 1
            return np.full((H, W), level(self.k), np.uint8)


@pytest.fixture
def open_camera() -> Iterator[Callable[..., OpenCvCamera]]:
    cameras: list[OpenCvCamera] = []

    def make(source: int | str, **kwargs: object) -> OpenCvCamera:
        kwargs.setdefault("name", "cam1")
        kwargs.setdefault("clock", WallClock())
        camera = OpenCvCamera(source, **kwargs)
        cameras.append(camera)
        return camera

    try:
        yield make
    finally:
        for camera in cameras:
            camera.close()


def grey_of(image: np.ndarray) -> int:
    return int(np.median(image))


# -- MJPEG over HTTP -------------------------------------------------------------------------
def test_reads_the_mjpeg_stream_with_its_resolution(serve, open_camera) -> None:
    frames = Counter()
    frames.k = 5
    server = serve(frames, fps=30)
    cam = open_camera(server.url)
    assert cam.image_size == (W, H)
    info = cam.identify()
    assert info["resolution"] == (W, H)
    assert info["source"] == server.url
    assert info["backend"] == "FFMPEG"
    assert info["live"] is True
    shot = cam.capture()
    assert shot.camera == "cam1"
    assert shot.image.dtype == np.uint8
    assert shot.image.shape == (H, W)
    assert abs(grey_of(shot.image) - level(5)) <= JPEG_DN


def test_colour_frames_are_rgb(serve, open_camera) -> None:
    rgb = np.zeros((H, W, 3), np.uint8)
    rgb[..., 0], rgb[..., 1], rgb[..., 2] = 200, 100, 30
    server = serve(lambda: rgb, fps=30)
    image = open_camera(server.url, grayscale=False).capture().image
    assert image.shape == (H, W, 3)
    np.testing.assert_allclose(np.median(image, axis=(0, 1)), [200, 100, 30], atol=JPEG_DN)


def test_capture_returns_a_frame_made_after_the_call(serve, open_camera) -> None:
    """The LEDs switch, then capture(): the frame returned shows the switch, every time."""
    frames = Counter()
    server = serve(frames, fps=20)
    clock = WallClock()
    cam = open_camera(server.url, clock=clock)
    stamps = []
    for k in range(1, 16):
        with frames.lock:
            frames.k = k
        before = clock.now()
        shot = cam.capture()
        assert abs(grey_of(shot.image) - level(k)) <= JPEG_DN, f"switch {k}: an older frame"
        assert shot.timestamp > before
        stamps.append(shot.timestamp)
    assert np.all(np.diff(stamps) > 0)


def test_stalled_stream_gives_no_frame_within_the_timeout_in_rig_seconds(
    serve, open_camera
) -> None:
    server = serve(Counter(), fps=30)
    # 5 rig seconds at 10 rig seconds per wall second: 0.5 s of waiting.
    cam = open_camera(server.url, clock=WallClock(time_scale=10.0), timeout_s=5.0)
    cam.capture()
    server.stalled = True
    t0 = time.monotonic()
    with pytest.raises(NoFrameError, match=r"no frame within 5\.0 s") as caught:
        cam.capture()
    waited = time.monotonic() - t0
    assert 0.45 <= waited < 2.0
    assert caught.value.camera == "cam1"
    server.stalled = False
    assert cam.capture().image.shape == (H, W)  # the camera delivers again


def test_a_dropped_connection_is_reopened(serve, open_camera) -> None:
    frames = Counter()
    server = serve(frames, fps=30)
    cam = open_camera(server.url, timeout_s=2.0)
    cam.capture()
    server.drop()
    with frames.lock:
        frames.k = 3
    assert abs(grey_of(cam.capture().image) - level(3)) <= JPEG_DN


def test_a_stream_gone_for_good_is_a_lost_device(serve, open_camera) -> None:
    server = serve(Counter(), fps=30)
    cam = open_camera(server.url, timeout_s=0.5)
    cam.capture()
    server.close()
    lost = None
    for _ in range(5):  # a capture may time out before the reader has given up reopening
        try:
            cam.capture()
        except NoFrameError:
            continue
        except DeviceLostError as exc:
            lost = exc
            break
    assert lost is not None, "the reader never gave the stream up"
    assert lost.device == "cam1"
    assert str(lost).startswith(f"cam1 on {server.url} (OpenCV): connection lost: the stream")
    assert "could not be reopened" in str(lost)


def test_unopenable_sources_are_lost_devices(serve, open_camera, tmp_path) -> None:
    server = serve(Counter())
    url = server.url
    server.close()  # nothing listens on its port any more
    for source in (url, str(tmp_path / "missing.avi"), str(tmp_path / "none_%04d.png")):
        with pytest.raises(DeviceLostError, match="cannot open") as caught:
            open_camera(source, name="camX", timeout_s=1.0)
        assert caught.value.device == "camX"


def test_a_wrong_image_size_is_named(serve, open_camera) -> None:
    server = serve(Counter())
    with pytest.raises(ValueError, match=r"cam1: image_size \(320, 240\).*\(160, 120\)"):
        open_camera(server.url, image_size=(320, 240))
    assert open_camera(server.url, image_size=(W, H)).image_size == (W, H)


def test_close_twice_stops_the_reader(serve, open_camera) -> None:
    server = serve(Counter())
    cam = open_camera(server.url, name="closing")
    cam.capture()
    cam.close()
    cam.close()
    assert not any(t.name == "camera-closing" for t in threading.enumerate())
    with pytest.raises(DeviceLostError, match="closed"):
        cam.capture()


# -- files ---------------------------------------------------------------------------------
def colour(k: int) -> tuple[int, int, int]:
    """(r, g, b) of frame ``k``."""
    return (20 + 40 * k, 200 - 30 * k, 60 + 10 * k)


def write_sequence(folder, first: int, count: int) -> str:
    folder.mkdir()
    for k in range(count):
        r, g, b = colour(k)
        bgr = np.zeros((48, 64, 3), np.uint8)
        bgr[...] = (b, g, r)
        assert cv2.imwrite(str(folder / f"{first + k:04d}.png"), bgr)
    return str(folder / "%04d.png")


@pytest.mark.parametrize("first", [0, 1, 7])
def test_image_sequence_gives_the_next_frame_then_ends(open_camera, tmp_path, first) -> None:
    pattern = write_sequence(tmp_path / "frames", first, 3)
    cam = open_camera(pattern, grayscale=False)
    assert cam.image_size == (64, 48)
    assert cam.identify()["live"] is False
    for k in range(3):
        image = cam.capture().image
        assert image.shape == (48, 64, 3)
        np.testing.assert_array_equal(image[0, 0], colour(k))
    with pytest.raises(NoFrameError, match="no more frames"):
        cam.capture()


def test_image_sequence_in_grey(open_camera, tmp_path) -> None:
    cam = open_camera(write_sequence(tmp_path / "grey", 0, 2))
    image = cam.capture().image
    assert image.shape == (48, 64)
    r, g, b = colour(0)
    assert abs(int(image[0, 0]) - (0.299 * r + 0.587 * g + 0.114 * b)) <= 1


def test_video_file(open_camera, tmp_path) -> None:
    path = str(tmp_path / "clip.avi")
    writer = cv2.VideoWriter(path, cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (W, H))
    assert writer.isOpened()
    try:
        for k in range(5):
            writer.write(np.full((H, W, 3), level(k), np.uint8))
    finally:
        writer.release()
    cam = open_camera(path)
    info = cam.identify()
    assert info["resolution"] == (W, H)
    assert info["fps"] == pytest.approx(10.0)
    for k in range(5):
        assert abs(grey_of(cam.capture().image) - level(k)) <= JPEG_DN
    with pytest.raises(NoFrameError):
        cam.capture()


def test_bad_arguments(open_camera) -> None:
    with pytest.raises(ValueError, match="settle_frames"):
        open_camera("x.avi", settle_frames=-1)
    with pytest.raises(ValueError, match="timeout_s"):
        open_camera("x.avi", timeout_s=0.0)


def test_video_logs_are_silenced_unless_the_user_asked_for_them(monkeypatch) -> None:
    logging = cv2.utils.logging
    before = logging.getLogLevel()
    try:
        logging.setLogLevel(logging.LOG_LEVEL_WARNING)
        monkeypatch.delenv("OPENCV_LOG_LEVEL", raising=False)
        monkeypatch.delenv("OPENCV_FFMPEG_LOGLEVEL", raising=False)
        quiet_video_logs()
        assert logging.getLogLevel() == logging.LOG_LEVEL_SILENT
        assert os.environ["OPENCV_FFMPEG_LOGLEVEL"] == FFMPEG_QUIET
        # Levels the user set are kept.
        logging.setLogLevel(logging.LOG_LEVEL_WARNING)
        monkeypatch.setenv("OPENCV_LOG_LEVEL", "WARNING")
        monkeypatch.setenv("OPENCV_FFMPEG_LOGLEVEL", "24")
        quiet_video_logs()
        assert logging.getLogLevel() == logging.LOG_LEVEL_WARNING
        assert os.environ["OPENCV_FFMPEG_LOGLEVEL"] == "24"
    finally:
        logging.setLogLevel(before)
