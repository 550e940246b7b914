"""The camera emulator: MJPEG over HTTP on localhost, the twin's LED frames, and the whole
chain (twin -> frames -> MJPEG -> OpenCV driver -> LED detection) against the twin's
geometric sensor."""

from __future__ import annotations

import http.client
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest

from calib.detection import SwitchingSequence
from twin.drivers.camera import OpenCvCamera
from twin.drivers.clock import WallClock
from twin.emulators.camera import BOUNDARY, MjpegServer, encode_jpeg
from twin.emulators.led_frames import GeometricLedFrames, RenderedLedFrames, gaussian_spot
from twin.hal.led_sensing import ImageLedSensor
from twin.scenario import load_scenario
from twin.sim.capture import CameraSimulator, led_radii
from twin.sim.rig import build_sim_rig
from twin.sim.rig.build import SimRig
from twin.sim.rig.leds import GeometricLedSensor, view_leds
from twin.sim.world import build_world

SMOKE = Path(__file__).resolve().parents[3] / "scenarios" / "smoke.toml"
W, H = 96, 64


def gradient() -> np.ndarray:
    """A smooth test frame JPEG keeps to a few DN."""
    u = np.linspace(30, 220, W)
    v = np.linspace(0, 20, H)
    return np.rint(u[None, :] + v[:, None]).astype(np.uint8)


def read_part(response: http.client.HTTPResponse) -> tuple[dict[str, str], bytes]:
    """One part of a multipart stream: its headers and body."""
    line = response.readline()
    while line in (b"\r\n", b"\n"):
        line = response.readline()
    assert line.strip() == f"--{BOUNDARY}".encode(), line
    headers = {}
    while (line := response.readline().strip()) != b"":
        key, value = line.decode("ascii").split(":", 1)
        headers[key.strip().lower()] = value.strip()
    return headers, response.read(int(headers["content-length"]))


def parts_until_end(response: http.client.HTTPResponse, most: int = 100) -> int:
    """Parts read before the stream ends (``most`` if it does not)."""
    for n in range(most):
        try:
            if response.readline() == b"":
                return n
            read_part(response)
        except (OSError, http.client.HTTPException, AssertionError, ValueError, KeyError):
            return n
    return most


def decode(data: bytes) -> np.ndarray:
    return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)


# -- the MJPEG server ------------------------------------------------------------------------
def test_stream_is_multipart_jpeg_made_when_due(serve) -> None:
    made = []

    def frames() -> np.ndarray:
        made.append(time.monotonic())
        return gradient()

    server = serve(frames, fps=40, quality=95)
    assert server.url == f"http://127.0.0.1:{server.port}/stream.mjpg"
    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=5)
    try:
        conn.request("GET", "/stream.mjpg")
        response = conn.getresponse()
        assert response.status == 200
        assert response.getheader("Content-Type") == (
            f"multipart/x-mixed-replace; boundary={BOUNDARY}"
        )
        for _ in range(4):
            headers, body = read_part(response)
            assert headers["content-type"] == "image/jpeg"
            image = decode(body)
            assert image.shape == (H, W)
            assert np.abs(image.astype(int) - gradient()).max() <= 3
    finally:
        conn.close()
    gaps = np.diff(made[:4])
    assert np.all(gaps > 0.5 / 40)  # one frame made per period, not ahead of time


def test_snapshot_and_unknown_paths(serve) -> None:
    rgb = np.zeros((H, W, 3), np.uint8)
    rgb[..., 0] = 180  # red
    server = serve(lambda: rgb)
    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=5)
    try:
        conn.request("GET", "/snapshot.jpg")
        response = conn.getresponse()
        assert response.status == 200
        assert response.getheader("Content-Type") == "image/jpeg"
        bgr = decode(response.read())
        np.testing.assert_allclose(np.median(bgr, axis=(0, 1)), [0, 0, 180], atol=3)
        conn.request("GET", "/other")
        missing = conn.getresponse()
        missing.read()
        assert missing.status == 404
    finally:
        conn.close()
    assert server.snapshot_url.endswith("/snapshot.jpg")


def test_stall_and_drop(serve) -> None:
    server = serve(gradient, fps=50)
    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=5)
    try:
        conn.request("GET", "/stream.mjpg")
        response = conn.getresponse()
        read_part(response)
        server.stalled = True
        time.sleep(0.05)  # a frame being sent when it stalled is let through
        sent = server.frames_sent
        time.sleep(0.2)
        assert server.frames_sent == sent
        server.stalled = False
        read_part(response)
        server.drop()
        assert parts_until_end(response) < 100  # what was already sent, then the end
    finally:
        conn.close()
    # A new connection is served after a drop.
    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=5)
    try:
        conn.request("GET", "/stream.mjpg")
        headers, _ = read_part(conn.getresponse())
        assert headers["content-type"] == "image/jpeg"
    finally:
        conn.close()


def test_close_twice_frees_the_port(serve) -> None:
    server = serve(gradient)
    port = server.port
    server.close()
    server.close()
    with pytest.raises(ConnectionRefusedError):
        http.client.HTTPConnection("127.0.0.1", port, timeout=2).request("GET", "/snapshot.jpg")
    with pytest.raises(RuntimeError, match="closed"):
        server.start()


def test_bad_frames_and_settings() -> None:
    with pytest.raises(ValueError, match="uint8"):
        encode_jpeg(np.zeros((4, 4), np.uint16))
    with pytest.raises(ValueError, match="quality"):
        encode_jpeg(np.zeros((4, 4), np.uint8), quality=0)
    with pytest.raises(ValueError, match="fps"):
        MjpegServer(gradient, fps=0.0)


# -- the twin's frames -----------------------------------------------------------------------
def test_gaussian_spot_is_centred_and_has_its_flux() -> None:
    image = np.zeros((40, 40))
    centre = np.array([17.3, 21.85])
    gaussian_spot(image, centre, 1.2, 100.0)
    v, u = np.mgrid[:40, :40]
    flux = image.sum()
    assert flux == pytest.approx(100.0 * 2 * np.pi * 1.2**2, rel=1e-6)
    np.testing.assert_allclose(
        [(u * image).sum() / flux, (v * image).sum() / flux], centre, atol=1e-6
    )


@pytest.fixture
def smoke() -> Iterator[SimRig]:
    world = build_world(load_scenario(SMOKE))
    sim = build_sim_rig(world, "geometric")
    try:
        yield sim
    finally:
        sim.close()


def test_geometric_frames_draw_the_lit_leds_the_camera_sees(smoke) -> None:
    world, leds = smoke.world, smoke.rig.leds
    # child2 right behind child1 as cam1 looks: some of its LEDs are hidden.
    world.place("child1", [3.0, 0.0], 0.0, settle=0.0)
    world.place("child2", [1.5, 0.0], 0.0, settle=0.0)
    lock = threading.RLock()
    frames = GeometricLedFrames(
        world, "cam1", leds, lock, np.random.default_rng(0), background=20.0, noise_dn=0.0
    )
    assert frames.image_size == (320, 240)
    np.testing.assert_array_equal(frames(), np.full((240, 320), 20, np.uint8))  # all dark
    model, radii = world.camera("cam1"), led_radii(world)
    views = {c: view_leds(world, model, c, radii) for c in leds}
    assert views["child1"].found.all()
    assert not views["child2"].found.all(), "child2 should be partly hidden by child1"
    leds["child1"].switch([True, False, True, False])
    leds["child2"].switch([True] * 4)
    drawn = {(c, k) for c, k, _, _ in frames.spots()}
    expected = {(c, k) for c, v in views.items() for k in np.flatnonzero(v.found)}
    expected -= {("child1", 1), ("child1", 3)}
    assert drawn == expected
    lit = frames().astype(float) - 20.0
    for c, k, pixel, _ in frames.spots():
        u, v = np.rint(pixel).astype(int)
        window = lit[v - 4 : v + 5, u - 4 : u + 5]
        vv, uu = np.mgrid[v - 4 : v + 5, u - 4 : u + 5]
        centroid = [(uu * window).sum() / window.sum(), (vv * window).sum() / window.sum()]
        np.testing.assert_allclose(centroid, pixel, atol=0.1, err_msg=f"{c} LED {k}")
    leds["child2"].hidden = frozenset({0})
    leds["child2"].switch([True] * 4)
    assert ("child2", 0) not in {(c, k) for c, k, _, _ in frames.spots()}


def test_rendered_frames_are_the_simulator_image(smoke) -> None:
    with CameraSimulator(smoke.world) as simulator:
        frames = RenderedLedFrames(simulator, "cam1", threading.RLock())
        image = frames()
    assert image.shape == (240, 320, 3)
    assert image.dtype == np.uint8
    assert image.std() > 1.0  # a scene, not a blank
    with pytest.raises(ValueError, match="no camera 'cam9'"):
        RenderedLedFrames(simulator, "cam9", threading.RLock())


def test_driver_finds_the_twin_leds_where_the_geometric_sensor_projects_them(smoke, serve):
    """Twin -> GeometricLedFrames -> MJPEG over HTTP -> OpenCvCamera -> ImageLedSensor."""
    world, leds = smoke.world, smoke.rig.leds
    lock = threading.RLock()
    with lock:
        world.place("child1", [2.5, 0.8], 0.3, settle=0.0)
    frames = GeometricLedFrames(world, "cam1", leds, lock, np.random.default_rng(3))
    server = serve(frames, fps=30)
    clock = WallClock()
    camera = OpenCvCamera(server.url, name="cam1", clock=clock, timeout_s=3.0)
    try:
        led_line = [float(p[2]) for p in world.scenario.marker.leds]
        sensor = ImageLedSensor(camera, leds, clock, led_line=led_line)
        truth = GeometricLedSensor(world, "cam1", clock, 0.0, np.random.default_rng(0))
        sequence = SwitchingSequence.binary(4)
        for child in ("child1", "child2"):
            expected = truth.observe(child, sequence)
            assert expected.complete, expected.failures
            seen = sensor.observe(child, sequence)
            assert seen.complete, seen.failures
            assert seen.frames == len(sequence.pattern)
            np.testing.assert_allclose(seen.pixels, expected.pixels, atol=0.5)
            # Well inside: the chain adds little to the detector's own noise.
            assert np.abs(seen.pixels - expected.pixels).max() < 0.2
            assert not any(any(leds[c].world.sensing.leds_on(c)) for c in leds)
    finally:
        camera.close()
