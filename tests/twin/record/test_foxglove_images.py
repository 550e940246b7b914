"""A render run's camera images in Foxglove's schemas: the calibrations are the cameras'
intrinsics, the annotations the LEDs found and the measured LED points projected through
the calibrated camera, one image per data stop."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import twin.sim  # noqa: F401  (headless OpenGL before mujoco is imported)
from calib.camera import TsaiCamera
from calib.detection.sequence import SwitchingSequence
from calib.io.camera_files import camera_from_dict, camera_to_dict
from twin.hal.devices import Camera
from twin.hal.led_sensing import ImageLedSensor
from twin.hal.readings import CameraImage
from twin.hal.recording import _RecordedLedSensor
from twin.record import McapRecorder, read_log
from twin.record.foxglove import FoxgloveStream
from twin.record.foxglove.images import (
    DETECTED,
    PROJECTED,
    RESIDUAL,
    TOPIC_SCHEMAS,
    annotation_px,
    calibration,
    camera_topics,
    jpeg,
)
from twin.run.runner import run_scenario

from .test_foxglove import ROOT, decoded, foxglove, layout_topics, seconds

SMALL = """
[campaign]
reference_points = 8
station_points = 12
min_points = 8
"""
"""The smoke room with few data stops: a render run of it takes about 15 s."""
TOPICS = camera_topics("cam1")


@pytest.fixture(scope="module")
def render(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("fox_render")
    scenario = folder / "small.toml"
    scenario.write_text((ROOT / "scenarios" / "smoke.toml").read_text() + SMALL)
    out = folder / "run"
    run_scenario(scenario, out, fidelity="render", report=False, seed=5, cameras=False)
    return out


def records(out: Path, topic: str) -> list:
    return [m for m in read_log(out / "log.mcap").messages if m.topic == topic]


def what(annotation) -> dict[str, list]:
    """A message's points annotations by their ``what``, as (N, 2) arrays."""
    out = {}
    for p in annotation.points:
        (kind,) = [kv.value for kv in p.metadata if kv.key == "what"]
        out[kind] = np.array([[q.x, q.y] for q in p.points]).reshape(-1, 2)
    return out


def test_the_camera_topics_have_foxglove_schemas(render):
    messages = foxglove(render / "log.mcap")
    for role, topic in TOPICS.items():
        assert {name for name, *_ in messages[topic]} == {TOPIC_SCHEMAS[role]}


def test_a_calibration_is_the_cameras_intrinsics(render):
    messages = foxglove(render / "log.mcap")
    (truth,) = records(render, "/truth/camera")
    (calibrated,) = records(render, "/campaign/calibration")
    for topic, model, frame in (
        (TOPICS["calibration_built"], truth.data["camera"], "camera/cam1/built"),
        (TOPICS["calibration"], calibrated.data["camera_model"], "camera/cam1/visit1"),
    ):
        ((_, _, message, _),) = messages[topic]
        camera = camera_from_dict(model)
        k = [[camera.sx * camera.f, 0, camera.cx], [0, camera.f, camera.cy], [0, 0, 1]]
        np.testing.assert_allclose(np.reshape(message.K, (3, 3)), k, rtol=1e-15, atol=0)
        np.testing.assert_allclose(np.reshape(message.P, (3, 4))[:, :3], k, rtol=1e-15)
        assert message.frame_id == frame
        assert (message.width, message.height) == camera.image_size == (320, 240)
        assert message.distortion_model in ("plumb_bob", "rational_polynomial")
    # The camera's frame is in /foxglove/tf.
    frames = {tf.child_frame_id for _, _, m, _ in messages["/foxglove/tf"] for tf in m.transforms}
    assert {"camera/cam1/built", "camera/cam1/visit1"} <= frames


def test_one_image_per_data_stop_at_its_observation(render):
    messages = foxglove(render / "log.mcap")
    stops = records(render, "/camera/cam1/leds")
    shown = messages[TOPICS["image"]]
    assert len(shown) == len(stops) > 5
    for (_, log_time, image, _), stop in zip(shown, stops, strict=True):
        assert log_time == round(stop.timestamp * 1e9)
        assert seconds(image.timestamp) == pytest.approx(stop.timestamp, abs=1e-9)
        assert image.format == "jpeg"
        assert image.frame_id == "camera/cam1/built"
        decoded = cv2.imdecode(np.frombuffer(image.data, np.uint8), cv2.IMREAD_COLOR)
        assert decoded.shape == (240, 320, 3)


def test_an_annotation_is_the_detected_centroid_recorded(render):
    messages = foxglove(render / "log.mcap")
    stops = records(render, "/camera/cam1/leds")
    at_image = messages[TOPICS["annotations"]][: len(stops)]
    for (_, log_time, annotation, _), stop in zip(at_image, stops, strict=True):
        assert log_time == round(stop.timestamp * 1e9)
        pixels = np.array(stop.data["pixels"], dtype=float)  # null: not found
        found = np.all(np.isfinite(pixels), axis=1)
        np.testing.assert_array_equal(what(annotation)[DETECTED], pixels[found] + 0.5)
        assert set(what(annotation)) == {DETECTED}  # no calibration yet
        labels = [t.text for t in annotation.texts]
        assert labels[:-1] == [f"LED {k}" for k in np.flatnonzero(found)]
        assert labels[-1].startswith(f"{stop.data['child']}: {found.sum()} of 4 LEDs found")


def test_a_projected_point_is_the_measured_point_through_the_calibration(render):
    messages = foxglove(render / "log.mcap")
    stops = records(render, "/camera/cam1/leds")
    (calibration,) = records(render, "/campaign/calibration")
    camera = camera_from_dict(calibration.data["camera_model"])
    points = [p for p in records(render, "/campaign/point") if p.data["dataset"] == "visit"]
    later = messages[TOPICS["annotations"]][len(stops) :]
    assert len(later) == len(points) > 0
    stamps = {round(s.timestamp * 1e9): s for s in stops}
    for (_, log_time, annotation, _), point in zip(later, points, strict=True):
        assert log_time == round(calibration.timestamp * 1e9)
        # Stamped as the image of the stop the point was taken at.
        stop = stamps[round(seconds(annotation.timestamp) * 1e9)]
        assert stop.timestamp <= point.timestamp
        leds = np.asarray(point.data["leds_world"], dtype=float)
        expected = camera.project(leds) + 0.5
        drawn = what(annotation)
        np.testing.assert_allclose(drawn[PROJECTED], expected, rtol=0, atol=1e-6)
        pixels = np.asarray(point.data["pixels"], dtype=float) + 0.5
        np.testing.assert_allclose(drawn[RESIDUAL], np.stack([pixels, expected], 1).reshape(-1, 2))


def test_the_layouts_image_panel_names_a_render_runs_topics(render):
    layout = json.loads((ROOT / "docs" / "foxglove-layout.json").read_text())
    topics, _, _ = layout_topics(layout)
    images = {t for t in topics if t.startswith("/foxglove/camera/")}
    assert images == {TOPICS["image"], TOPICS["annotations"], TOPICS["calibration"]}
    assert images <= set(foxglove(render / "log.mcap"))


class Frames(Camera):
    """A camera whose k-th image is all ``k``, but for one bright pixel at (k, k)."""

    def __init__(self) -> None:
        self.k = 0

    name = "cam1"
    image_size = (16, 16)

    def capture(self) -> CameraImage:
        self.k += 1
        image = np.full((16, 16), self.k, dtype=np.uint8)
        image[self.k, self.k] = 200
        return CameraImage("cam1", float(self.k), image)

    def close(self) -> None:
        pass


class Leds:
    child, count = "child1", 2

    def switch(self, on):
        pass


class Clock:
    def now(self) -> float:
        return 9.0


class Images:
    def __init__(self) -> None:
        self.records, self.images = [], []

    def record(self, topic, record, timestamp):
        self.records.append(topic)

    def image(self, camera, image, timestamp):
        self.images.append((camera, image, timestamp))


def test_the_image_of_an_observation_is_its_frames_at_their_brightest():
    sensor = ImageLedSensor(Frames(), {"child1": Leds()}, Clock(), scene_retries=0)
    assert sensor.last_image() is None
    recorder = Images()
    obs = _RecordedLedSensor(sensor, recorder).observe("child1", SwitchingSequence.binary(2))
    (camera, image, t), n = recorder.images[0], obs.frames
    assert (camera, t, recorder.records) == ("cam1", obs.timestamp, ["/camera/cam1/leds"])
    expected = np.full((16, 16), n, dtype=np.uint8)
    for k in range(1, n + 1):
        expected[k, k] = 200
    np.testing.assert_array_equal(image.image, expected)
    assert image.timestamp == float(n)  # the last frame's


def test_a_recorder_without_images_gets_none():
    class Plain:
        def __init__(self) -> None:
            self.records: list[str] = []

        def record(self, topic, record, timestamp):
            self.records.append(topic)

    sensor = ImageLedSensor(Frames(), {"child1": Leds()}, Clock(), scene_retries=0)
    recorder = Plain()
    _RecordedLedSensor(sensor, recorder).observe("child1", SwitchingSequence.binary(2))
    assert recorder.records == ["/camera/cam1/leds"]
    assert sensor.last_image() is not None  # taken, and not handed to the recorder


def test_a_16_bit_image_is_scaled_to_its_highest_value():
    image = np.array([[0, 1000], [2000, 4000]], dtype=np.uint16)
    back = cv2.imdecode(np.frombuffer(jpeg(image), np.uint8), cv2.IMREAD_GRAYSCALE)
    np.testing.assert_allclose(back, [[0, 64], [128, 255]], atol=8)


@pytest.mark.parametrize(
    ("image", "said"),
    [
        (np.zeros((4, 4), np.float32), "uint8 or uint16, got float32"),
        (np.zeros((4, 4, 2), np.uint8), "(H, W) or (H, W, 3), got (4, 4, 2)"),
    ],
)
def test_an_image_that_cannot_be_encoded_is_named(image, said):
    with pytest.raises(ValueError, match=said.replace("(", r"\(").replace(")", r"\)")):
        jpeg(image)


def test_an_annotation_is_the_pixel_plus_half_a_pixel():
    np.testing.assert_array_equal(
        annotation_px([[0.0, 0.0], [319.0, 239.0]]), [[0.5, 0.5], [319.5, 239.5]]
    )


def test_an_image_that_cannot_be_drawn_is_logged_and_the_run_goes_on(tmp_path):
    path = tmp_path / "log.mcap"
    observed = {"camera": "cam1", "child": "child1", "pixels": [[1.0, 2.0]], "failures": [None]}
    with McapRecorder(path, foxglove=FoxgloveStream()) as recorder:
        recorder.record("/camera/cam1/leds", observed, 1.0)
        recorder.image("cam1", CameraImage("cam1", 1.0, np.zeros((4, 4), np.float32)), 1.0)
        recorder.image("cam1", CameraImage("cam1", 2.0, np.zeros((4, 4), np.uint8)), 2.0)
    messages = foxglove(path)
    (line,) = [m for _, _, m, _ in messages["/foxglove/log"]]
    assert "cannot draw the record on /camera/cam1/image: ValueError" in line.message
    assert "uint8 or uint16, got float32" in line.message
    assert [t for _, t, _, _ in messages[TOPICS["image"]]] == [2_000_000_000]
    assert [m.topic for m in read_log(path).messages] == ["/camera/cam1/leds"]  # no record


def test_a_recorder_without_foxglove_takes_no_image(tmp_path):
    path = tmp_path / "log.mcap"
    with McapRecorder(path) as recorder:
        recorder.image("cam1", CameraImage("cam1", 1.0, np.zeros((4, 4), np.uint8)), 1.0)
    assert foxglove(path) == {}


@settings(max_examples=20, deadline=None)
@given(
    f=st.floats(200.0, 2000.0),
    sx=st.floats(0.9, 1.1),
    cx=st.floats(100.0, 220.0),
    cy=st.floats(80.0, 160.0),
    kappa1=st.floats(-3e-7, 3e-7),
)
def test_a_calibrations_k_is_the_tsai_intrinsics(f, sx, cx, cy, kappa1):
    camera = TsaiCamera(f, cx, cy, kappa1, sx, np.eye(3), np.array([0.0, 0.0, 1.0]))
    message = decoded(calibration(2.5, "camera/c/visit1", camera_to_dict(camera)))
    k = np.reshape(message.K, (3, 3))
    np.testing.assert_array_equal(k, [[sx * f, 0, cx], [0, f, cy], [0, 0, 1]])
    assert len(message.D) == {"plumb_bob": 5, "rational_polynomial": 8}[message.distortion_model]
    assert message.frame_id == "camera/c/visit1"
    assert seconds(message.timestamp) == 2.5
