"""Foxglove's channels in a run's log: Foxglove's schemas, read back with ``mcap`` and the
SDK's protobuf schemas, drawing exactly what the records and results say; an older log
converts with ``twin replay --foxglove``."""

from __future__ import annotations

import json
import math
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from foxglove.messages import Pose
from hypothesis import given
from hypothesis import strategies as st
from mcap.reader import make_reader
from mcap.records import Schema
from mcap_protobuf.decoder import DecoderFactory
from scipy.spatial.transform import Rotation

from calib.io.camera_files import camera_from_dict
from twin.cli import main
from twin.instruments.polar import polar2cartesian
from twin.instruments.tilt import level_points
from twin.record import McapRecorder, read_log
from twin.record.foxglove import TOPICS, FoxgloveStream
from twin.record.foxglove import scene as fox_scene
from twin.record.foxglove.convert import quaternion, timestamp
from twin.record.foxglove.stream import _levelled
from twin.run.runner import run_scenario

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"
WHICH = ("estimate", "truth")


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("fox")
    results = run_scenario(SMOKE, out, fidelity="geometric", report=False, seed=5)
    return out, results


def run_results(folder: Path) -> dict:
    """A run's results without what the machine's clock put in them."""
    results = json.loads((folder / "results.json").read_text())
    results.pop("wall_time_s"), results.pop("timings_s")
    return results


def run_records(folder: Path) -> list[tuple[str, float, dict]]:
    """A run's records (topic, time, data) without what the machine's clock put in them."""
    kept = []
    for m in read_log(folder / "log.mcap").messages:
        data = {k: v for k, v in m.data.items() if k not in ("started", "wall_time_s")}
        data.pop("timings_s", None)
        kept.append((m.topic, m.timestamp, data))
    return kept


def foxglove(path: Path) -> dict[str, list[tuple[str, int, Any, bytes]]]:
    """The Foxglove messages of a log by topic: (schema name, log time ns, decoded, raw)."""
    factory = DecoderFactory()
    out: dict[str, list] = defaultdict(list)
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            if channel.message_encoding != "protobuf":
                continue
            decoded = factory.decoder_for("protobuf", schema)(message.data)
            out[channel.topic].append((schema.name, message.log_time, decoded, message.data))
    return dict(out)


def transforms(messages: dict, child: str) -> list[Any]:
    """Every transform of ``child`` in the log's frame transforms."""
    return [
        tf
        for _, _, m, _ in messages["/foxglove/tf"]
        for tf in m.transforms
        if tf.child_frame_id == child
    ]


def seconds(stamp: Any) -> float:
    return (
        stamp.sec + stamp.nanosec * 1e-9
        if hasattr(stamp, "nanosec")
        else stamp.ToNanoseconds() * 1e-9
    )


def decoded(message: Any) -> Any:
    """A Foxglove message of the SDK as the protobuf message a reader decodes."""
    schema = type(message).get_schema()
    record = Schema(id=1, name=schema.name, encoding=schema.encoding, data=schema.data)
    return DecoderFactory().decoder_for("protobuf", record)(message.encode())


def xyz(v: Any) -> np.ndarray:
    return np.array([v.x, v.y, v.z])


def rotation(q: Any) -> np.ndarray:
    return Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()


def test_the_log_holds_foxglove_channels_with_their_schemas(run):
    out, _ = run
    messages = foxglove(out / "log.mcap")
    tracks = {f"/foxglove/track/{c}_{w}" for c in ("child1", "child2") for w in WHICH}
    assert set(messages) == set(TOPICS) | tracks  # the smoke run gives every channel
    for topic, items in messages.items():
        assert {name for name, *_ in items} == {TOPICS.get(topic, "foxglove.PosesInFrame")}
    # The geometric fidelity takes no images: no camera's image channels.
    assert not [t for t in messages if t.startswith("/foxglove/camera/")]
    assert {e.id for _, _, m, _ in messages["/foxglove/scene/site"] for e in m.entities} == {
        "floor",
        "walls",
        "obstacles",
        "route",
        "stations",
    }
    # The records read back as before: read_log leaves the Foxglove channels out.
    assert not [t for t in read_log(out / "log.mcap").topics if t.startswith("/foxglove")]


def test_a_run_without_the_channels_has_the_same_records_and_results(run, tmp_path):
    # A Monte-Carlo trial's settings: its log is read for the rows and thrown away.
    out, _ = run
    plain = tmp_path / "plain"
    run_scenario(
        SMOKE, plain, fidelity="geometric", report=False, seed=5, foxglove=False, cameras=False
    )
    assert foxglove(plain / "log.mcap") == {}
    assert run_records(plain) == run_records(out)
    assert run_results(plain) == run_results(out)


def test_a_calibrated_camera_frame_is_its_results_pose(run):
    out, results = run
    messages = foxglove(out / "log.mcap")
    (tf,) = transforms(messages, "camera/cam1/visit1")
    calibration = results["calibrations"][0]
    position_m = np.asarray(calibration["parameters"]["position_mm"]) / 1000.0
    assert tf.parent_frame_id == "W"
    np.testing.assert_allclose(xyz(tf.translation), position_m, rtol=0, atol=1e-9)
    # The frame is the camera's optical frame: its z axis is the optical axis, in W.
    record = next(
        m for m in read_log(out / "log.mcap").messages if m.topic == "/campaign/calibration"
    )
    camera = camera_from_dict(record.data["camera_model"])
    np.testing.assert_allclose(rotation(tf.rotation), camera.world2cam_r.T, atol=1e-9)
    (built,) = transforms(messages, "camera/cam1/built")
    np.testing.assert_allclose(
        xyz(built.translation), np.asarray(calibration["truth"]["position_mm"]) / 1e3, atol=1e-9
    )


def test_an_led_point_in_the_scene_is_its_point_record(run):
    out, _ = run
    messages = foxglove(out / "log.mcap")
    points = [m for m in read_log(out / "log.mcap").messages if m.topic == "/campaign/point"]
    entities = {}
    for _, _, m, _ in messages["/foxglove/scene/points"]:
        for e in m.entities:
            entities.setdefault(e.id, e)  # as first drawn, when the point was taken
    first, last = points[0].data, points[-1].data
    for record, k in ((first, 0), (last, None)):
        key = (record["camera"], record["visit"])
        mine = [p for p in points if (p.data["camera"], p.data["visit"]) == key]
        n = mine.index(next(p for p in mine if p.data is record)) if k is None else k
        e = entities[f"{record['dataset']}/{record['camera']}/visit{record['visit']}/{n}"]
        drawn = np.array([xyz(s.pose.position) for s in e.spheres])
        np.testing.assert_allclose(drawn, np.asarray(record["leds_world"]), rtol=0, atol=1e-12)


def test_the_points_of_a_visit_are_coloured_by_their_calibration_residual(run):
    out, results = run
    messages = foxglove(out / "log.mcap")
    calibration = results["calibrations"][0]
    residuals = []
    for _, _, m, _ in messages["/foxglove/scene/points"]:
        for e in m.entities:
            meta = {kv.key: kv.value for kv in e.metadata}
            if e.id.startswith("visit/cam1/visit1/") and "residuals_px" in meta:
                residuals += [float(v) for v in meta["residuals_px"].split()]
    expected = np.hypot(*np.asarray(calibration["residuals_px"]).T)
    n = calibration["points"]
    np.testing.assert_allclose(residuals[:n], expected, atol=1e-3)  # written to 1e-3 px


def test_the_parents_frames_at_a_fix_are_its_truth_and_its_estimate(run):
    out, _ = run
    messages = foxglove(out / "log.mcap")
    log = read_log(out / "log.mcap").messages
    truths = [m.data for m in log if m.topic == "/truth/instrument"]
    fixes = [m.data for m in log if m.topic == "/campaign/parent_fix"]
    true_frames = transforms(messages, "instrument/truth")
    estimates = transforms(messages, "instrument/estimate")
    assert len(true_frames) == len(truths) >= 2
    assert len(estimates) == len(fixes) >= 2
    for tf, truth in zip(true_frames, truths, strict=True):
        np.testing.assert_allclose(xyz(tf.translation), truth["translation"], rtol=0, atol=1e-12)
        yaw = Rotation.from_matrix(rotation(tf.rotation)).as_euler("ZYX")[0]
        assert yaw == pytest.approx(truth["yaw"], abs=1e-12)
    for tf, fix in zip(estimates, fixes, strict=True):
        np.testing.assert_allclose(xyz(tf.translation), fix["translation"], rtol=0, atol=1e-12)
    # At the last fix, the covariance's ellipsoid: 3 sigma, magnified 100 times.
    (_, _, update, _) = messages["/foxglove/scene/parent_covariance"][-1]
    (sphere,) = update.entities[-1].spheres
    cov = np.asarray(fixes[-1]["covariance"])[1:, 1:]
    sigmas = np.sqrt(np.linalg.eigvalsh(cov))
    np.testing.assert_allclose(
        sorted(xyz(sphere.size)), sorted(2 * 3.0 * 100.0 * sigmas), rtol=1e-9
    )
    np.testing.assert_allclose(xyz(sphere.pose.position), fixes[-1]["translation"], atol=1e-12)


def test_a_line_of_sight_is_as_long_as_its_shot(run):
    out, _ = run
    messages = foxglove(out / "log.mcap")
    shots = [
        m.data for m in read_log(out / "log.mcap").messages if m.topic == "/total_station/shot"
    ]
    lines = [
        e.lines[0] for _, _, m, _ in messages["/foxglove/scene/lines_of_sight"] for e in m.entities
    ]
    assert len(lines) == len(shots)
    for line, shot in zip(lines, shots, strict=True):
        length = np.linalg.norm(xyz(line.points[1]) - xyz(line.points[0]))
        assert length == pytest.approx(shot["distance"], abs=1e-9)


def test_failures_and_events_are_foxglove_log_lines(run):
    out, _ = run
    messages = foxglove(out / "log.mcap")
    log = read_log(out / "log.mcap").messages
    failures = [m for m in log if m.topic == "/campaign/failure"]
    lines = [m for _, _, m, _ in messages["/foxglove/log"] if m.name == "/campaign/failure"]
    assert len(lines) == len(failures) > 0
    assert lines[0].message.startswith(failures[0].data["kind"] + ":")
    assert seconds(lines[0].timestamp) == pytest.approx(failures[0].timestamp, abs=1e-9)


def test_a_replay_writes_the_runs_foxglove_messages(run, tmp_path):
    out, _ = run
    target = tmp_path / "fox.mcap"
    assert main(["replay", str(out / "log.mcap"), "--foxglove", str(target)]) == 0
    ran, replayed = foxglove(out / "log.mcap"), foxglove(target)
    assert set(ran) == set(replayed)
    for topic in ran:
        assert [raw for *_, raw in ran[topic]] == [raw for *_, raw in replayed[topic]], topic
    assert [m.data for m in read_log(target).messages] == [
        m.data for m in read_log(out / "log.mcap").messages
    ]


def test_an_older_log_converts_and_what_it_lacks_is_said(run, tmp_path, capsys):
    out, _ = run
    old = tmp_path / "old.mcap"
    # As an older version wrote it: no Foxglove channels, no truth, no scenario digest.
    with McapRecorder(old) as recorder:
        for m in read_log(out / "log.mcap").messages:
            if m.topic.startswith("/truth/"):
                continue
            data = m.data
            if m.topic == "/run/meta":
                data = {
                    k: v for k, v in data.items() if k not in ("scenario_digest", "scenario_path")
                }
            recorder.record(m.topic, data, m.timestamp)
    assert not foxglove(old)
    target = tmp_path / "converted.mcap"
    code = main(["replay", str(old), "--foxglove", str(target), "--scenario", str(SMOKE)])
    said = capsys.readouterr().out
    assert code == 0
    assert "no cameras as built (/truth/camera)" in said
    assert "no instrument truth" in said
    assert "no robots' true poses (/truth/robot)" in said
    messages = foxglove(target)
    assert "/foxglove/track/instrument_truth" not in messages
    assert transforms(messages, "camera/cam1/visit1")
    assert not transforms(messages, "camera/cam1/built")
    assert "/foxglove/scene/site" in messages


def test_bad_foxglove_targets_are_named(run, tmp_path, capsys):
    out, _ = run
    log = out / "log.mcap"
    for target, expected in (
        (tmp_path, "is a folder"),
        (log, "is the log itself"),
        (SMOKE, "exists; name a new file or pass --overwrite"),
    ):
        before = sorted(tmp_path.iterdir())
        assert main(["replay", str(log), "--foxglove", str(target)]) == 2
        said = capsys.readouterr().out
        assert f"--foxglove {target}" in said
        assert expected in said
        assert sorted(tmp_path.iterdir()) == before


@given(st.floats(min_value=0.0, max_value=1e9, allow_nan=False))
def test_a_timestamp_is_the_records_in_ns(t):
    stamp = timestamp(t)
    assert 0 <= stamp.nsec < 1_000_000_000
    assert stamp.sec * 1_000_000_000 + stamp.nsec == round(t * 1e9)


@given(st.lists(st.floats(-math.pi, math.pi), min_size=3, max_size=3))
def test_a_quaternion_is_its_rotation(angles):
    r = Rotation.from_euler("xyz", angles).as_matrix()
    q = decoded(Pose(orientation=quaternion(r))).orientation
    assert math.isclose(q.x**2 + q.y**2 + q.z**2 + q.w**2, 1.0, rel_tol=1e-12)
    np.testing.assert_allclose(rotation(q), r, atol=1e-12)


def test_a_covariance_that_is_not_positive_draws_no_ellipsoid():
    assert fox_scene.ellipsoid_entity(0.0, "fix0", np.zeros(3), np.zeros((3, 3))) is None
    assert fox_scene.ellipsoid_entity(0.0, "fix0", np.zeros(3), np.full((3, 3), np.nan)) is None
    drawn = fox_scene.ellipsoid_entity(0.0, "fix1", np.ones(3), np.diag([1e-6, 4e-6, 9e-6]))
    assert drawn is not None
    e = decoded(drawn)
    np.testing.assert_allclose(sorted(xyz(e.spheres[0].size)), [0.6, 1.2, 1.8], rtol=1e-12)


@given(
    st.floats(0.5, 2000.0),
    st.floats(0.0, 2 * math.pi),
    st.floats(0.0, math.pi),
    st.floats(-0.02, 0.02),
    st.floats(-0.02, 0.02),
)
def test_a_shot_is_drawn_where_the_instrument_levels_it(d, hz, v, roll, pitch):
    drawn = np.array(_levelled(d, hz, v, roll, pitch))
    expected = level_points(polar2cartesian([d, hz, v]), roll, pitch)
    np.testing.assert_allclose(drawn, expected, rtol=0, atol=1e-12 * d)


def test_a_record_that_cannot_be_drawn_is_logged_and_kept(tmp_path):
    path = tmp_path / "log.mcap"
    with McapRecorder(path, foxglove=FoxgloveStream()) as recorder:
        recorder.record("/campaign/parent_fix", {"index": 3, "translation": [0, 0, 0]}, 2.0)
        recorder.record("/truth/instrument", {"translation": [1.0, 2.0, 0.0], "yaw": 0.5}, 3.0)
    assert [m.topic for m in read_log(path).messages] == [
        "/campaign/parent_fix",
        "/truth/instrument",
    ]
    messages = foxglove(path)
    (line,) = [m for _, _, m, _ in messages["/foxglove/log"]]
    assert "cannot draw the record on /campaign/parent_fix: KeyError" in line.message
    assert line.level == 4  # ERROR
    (tf,) = transforms(messages, "instrument/truth")  # the next record is drawn
    np.testing.assert_allclose(xyz(tf.translation), [1.0, 2.0, 0.0])


def test_a_childs_tracks_are_its_placements_and_its_truth(run):
    out, _ = run
    messages = foxglove(out / "log.mcap")
    log = read_log(out / "log.mcap").messages
    fixes = [m.timestamp for m in log if m.topic == "/campaign/parent_fix"]
    (end,) = [m.timestamp for m in log if m.topic == "/run/summary"]
    for child in ("child1", "child2"):
        placed = [m for m in log if m.topic == f"/base/{child}/set_pose"]
        truths = [m for m in log if m.topic == "/truth/robot" and m.data["robot"] == child]
        for which, records in (("estimate", placed), ("truth", truths)):
            sent = messages[f"/foxglove/track/{child}_{which}"]
            assert len(sent) <= len(fixes) + 1
            for _, log_time, track, _ in sent:  # sent at fixes and at the end, whole
                assert log_time / 1e9 in [*fixes, end]
                assert track.frame_id == "W"
                before = [r for r in records if r.timestamp <= log_time / 1e9]
                assert len(track.poses) == len(before) > 0
            (*_, last, _) = sent[-1]
            assert len(last.poses) == len(records) >= 2
            for p, r in zip(last.poses, records, strict=True):
                if which == "estimate":
                    expected, yaw = [r.data["x"], r.data["y"], -0.40], r.data["yaw"]
                    turn = Rotation.from_euler("z", yaw).as_matrix()
                else:
                    expected, turn = r.data["translation"], r.data["rotation"]
                np.testing.assert_allclose(xyz(p.position), expected, rtol=0, atol=1e-12)
                np.testing.assert_allclose(rotation(p.orientation), turn, atol=1e-9)


def test_the_prisms_and_leds_are_drawn_on_each_child(run):
    from twin.scenario import load_scenario

    out, _ = run
    marker = load_scenario(SMOKE).marker.assembly()
    ((_, log_time, update, _),) = foxglove(out / "log.mcap")["/foxglove/scene/robots"]
    assert log_time == 0
    drawn = {e.id: e for e in update.entities}
    assert set(drawn) == {f"{c}/{w}" for c in ("child1", "child2") for w in WHICH}
    for id_, e in drawn.items():
        assert e.frame_id == id_  # the robot's frame: the body frame of the assembly
        assert e.frame_locked
        centres = np.array([xyz(s.pose.position) for s in e.spheres])
        np.testing.assert_array_equal(centres[:3], marker.cubes_body)
        np.testing.assert_array_equal(centres[3:], marker.leds_body)


def test_each_robot_has_its_true_and_estimated_frames(run):
    out, _ = run
    messages = foxglove(out / "log.mcap")
    log = read_log(out / "log.mcap").messages
    truths = [m.data for m in log if m.topic == "/truth/robot" and m.data["robot"] == "child1"]
    frames = transforms(messages, "child1/truth")
    assert len(frames) == len(truths) >= 2
    for tf, truth in zip(frames, truths, strict=True):
        np.testing.assert_allclose(xyz(tf.translation), truth["translation"], rtol=0, atol=1e-12)
        np.testing.assert_allclose(rotation(tf.rotation), truth["rotation"], atol=1e-9)
    placed = [m for m in log if m.topic == "/base/child1/set_pose"][-1]
    estimate = [tf for tf in transforms(messages, "child1/estimate")][-1]
    np.testing.assert_allclose(
        xyz(estimate.translation), [placed.data["x"], placed.data["y"], -0.40], atol=1e-12
    )
    assert transforms(messages, "parent/estimate")


def layout_topics(node: Any) -> tuple[set[str], set[str], set[str]]:
    """What a layout names: topics, message paths (of plots) and frames."""
    topics: set[str] = set()
    paths: set[str] = set()
    frames: set[str] = set()
    if isinstance(node, dict):
        for key, value in node.items():
            if key in ("topics", "annotations"):
                topics |= set(value)
            elif key in ("topicToRender", "imageTopic", "calibrationTopic"):
                topics.add(value)
            elif key == "value" and isinstance(value, str):
                paths.add(value)
            elif key in ("followTf", "fixedFrame"):
                frames.add(value)
            more = layout_topics(value)
            topics, paths, frames = topics | more[0], paths | more[1], frames | more[2]
    elif isinstance(node, list):
        for value in node:
            more = layout_topics(value)
            topics, paths, frames = topics | more[0], paths | more[1], frames | more[2]
    return topics, paths, frames


def test_the_shipped_layout_names_only_what_a_log_holds(run):
    import json
    import re

    from twin.record.foxglove.layout import layout_json

    text = (ROOT / "docs" / "foxglove-layout.json").read_text()
    assert text == layout_json()  # the shipped file is the layout's code
    layout = json.loads(text)
    topics, paths, frame_ids = layout_topics(layout)
    out, _ = run
    fox = foxglove(out / "log.mcap")
    records = read_log(out / "log.mcap")
    assert topics
    # A camera's image topics are in a render run's log (test_foxglove_images.py).
    images = {t for t in topics if t.startswith("/foxglove/camera/")}
    assert len(images) == 3
    assert topics - images <= set(fox) | set(records.topics)
    assert len(paths) == 4
    for path in paths:
        topic, rest = re.fullmatch(r"(/[^.]+)\.(.+)", path).groups()
        data = next(m.data for m in records.messages if m.topic == topic)
        for part in re.findall(r"\w+|\[\d+\]", rest):  # every field and index resolves
            data = data[int(part[1:-1])] if part.startswith("[") else data[part]
        assert isinstance(data, float)
    children = {tf.child_frame_id for _, _, m, _ in fox["/foxglove/tf"] for tf in m.transforms}
    parents = {tf.parent_frame_id for _, _, m, _ in fox["/foxglove/tf"] for tf in m.transforms}
    assert frame_ids <= children | parents


def test_the_headless_scene_is_what_the_scene_updates_say(run, tmp_path, capsys):
    from twin.record.foxglove import figure

    out, results = run
    drawn = figure.read_scene(out / "log.mcap")
    frustums = [s for s in drawn.segments if not s[2] and len(s[0]) == 16]
    built = [m for m in read_log(out / "log.mcap").messages if m.topic == "/truth/camera"]
    assert len(frustums) == len(built) + len(results["calibrations"])
    led = np.array(
        next(m.data for m in read_log(out / "log.mcap").messages if m.topic == "/campaign/point")[
            "leds_world"
        ][0]
    )
    centres = np.array([p for p, size, _ in drawn.spheres if size[0] == fox_scene.LED_SIZE_M])
    assert np.min(np.linalg.norm(centres - led, axis=1)) < 1e-9
    png = tmp_path / "scene.png"
    assert figure.main([str(out / "log.mcap"), str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    empty = tmp_path / "empty.mcap"
    with McapRecorder(empty):
        pass
    assert figure.main([str(empty), str(tmp_path / "none.png")]) == 2
    assert f"{empty}: the log has no foxglove.SceneUpdate" in capsys.readouterr().err
    assert not (tmp_path / "none.png").exists()
