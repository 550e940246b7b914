"""The MCAP run log: write, read back, survive a kill and a cut anywhere."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from twin.hal.readings import (
    DriveResult,
    DriveStatus,
    Event,
    LedObservation,
    LedSwitch,
    OdometryReading,
    TiltReading,
    TotalStationMeasurement,
)
from twin.record import LogContents, McapRecorder, decode, encode, read_log

REPO = Path(__file__).resolve().parents[3]


def sample_records() -> list[tuple[str, object, float]]:
    """(topic, record, timestamp s): one of each record type, NaNs included."""
    tilt = TiltReading(0.5, 1e-5, -2e-5)
    odo = OdometryReading("child_1", 2.0, 1.0, 2.0, 0.5)
    return [
        ("/total_station/inclination", tilt, 0.5),
        ("/total_station/shot", TotalStationMeasurement(1.0, 5.0, 1.0, 1.5, tilt), 1.0),
        ("/base/child_1/odometry", odo, 2.0),
        (
            "/base/child_1/drive",
            DriveResult("child_1", 3.0, [1.0, 2.0, math.nan], DriveStatus.BLOCKED, odo, 1.0),
            3.0,
        ),
        ("/leds/child_1", LedSwitch("child_1", 4.0, (True, False)), 4.0),
        (
            "/camera/cam_0/leds",
            LedObservation(
                "cam_0",
                "child_1",
                5.0,
                [[10.0, 20.0], [math.nan, math.nan]],
                [0.1, math.nan],
                (None, "occluded"),
                6,
            ),
            5.0,
        ),
        ("/total_station/failure", Event(6.0, "lost_lock", "no prism", {"aim": [1, 2]}), 6.0),
        ("/notes", {"text": "plain mapping", "n": 3}, 7.0),
    ]


def write_log(path: Path, entries: list[tuple[str, object, float]], **kw: int) -> None:
    with McapRecorder(path, **kw) as rec:
        for topic, record, t in entries:
            rec.record(topic, record, t)
        assert rec.count == len(entries)


def test_write_and_read_back(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    entries = sample_records()
    write_log(path, entries)
    log = read_log(path)
    assert isinstance(log, LogContents)
    assert log.complete
    assert log.unread_bytes == 0
    assert [m.topic for m in log.messages] == [e[0] for e in entries]
    assert [m.timestamp for m in log.messages] == [e[2] for e in entries]
    assert log.messages[0].data == encode(entries[0][1])
    assert log.topics == tuple(e[0] for e in entries)
    for (_, record, _), back in zip(entries, log.records(), strict=True):
        assert json.dumps(encode(back), allow_nan=False) == json.dumps(encode(record))
    assert log.records("/notes") == [{"text": "plain mapping", "n": 3}]
    assert [type(r) for r in log.records("/total_station")] == [
        TiltReading,
        TotalStationMeasurement,
        Event,
    ]


def test_timestamps_in_ns_clamped_at_zero(tmp_path: Path) -> None:
    path = tmp_path / "t.mcap"
    with McapRecorder(path) as rec:
        rec.record("/t", {"k": 1}, -3.0)
        rec.record("/t", {"k": 2}, 1.2345678914)
        with pytest.raises(ValueError, match=r"'/t'.*finite"):
            rec.record("/t", {"k": 3}, math.nan)
        assert rec.count == 2
    assert [m.timestamp for m in read_log(path).messages] == [0.0, 1.234567891]


def test_one_topic_carries_several_types(tmp_path: Path) -> None:
    path = tmp_path / "mixed.mcap"
    write_log(path, [("/x", TiltReading(1.0, 0.0, 0.0), 1.0), ("/x", {"a": 1}, 2.0)])
    log = read_log(path)
    assert log.topics == ("/x",)
    assert isinstance(log.records()[0], TiltReading)


def test_recorder_rejects_bad_use(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="flush_every"):
        McapRecorder(tmp_path / "a.mcap", flush_every=0)
    rec = McapRecorder(tmp_path / "b.mcap")
    with pytest.raises(TypeError, match="set"):
        rec.record("/x", {"s": {1}}, 0.0)
    rec.close()
    rec.close()
    with pytest.raises(ValueError, match="closed"):
        rec.record("/x", {}, 0.0)
    assert read_log(tmp_path / "b.mcap").messages == []


_WRITER = """
import sys, time
from twin.hal.readings import Event, LedObservation, OdometryReading
from twin.record import McapRecorder

rec = McapRecorder(sys.argv[1], flush_every=4)
k = 0
deadline = time.monotonic() + 20.0
while time.monotonic() < deadline:
    t = 0.1 * k
    if k % 3 == 0:
        r = OdometryReading("a", t, float(k), 0.0, 0.0)
    elif k % 3 == 1:
        r = LedObservation("cam", "a", t, [[1.0, float(k)], [float("nan")] * 2],
                           [0.1, float("nan")], (None, "occluded"), k)
    else:
        r = Event(t, "tick", "x" * (k % 50), {"k": k})
    rec.record(f"/topic/{k % 3}", r, t)
    k += 1
    if rec.count % 4 == 0:
        print(rec.count, flush=True)
    time.sleep(0.0005)
"""


def test_killed_writer_leaves_flushed_messages(tmp_path: Path) -> None:
    path = tmp_path / "killed.mcap"
    proc = subprocess.Popen(
        [sys.executable, "-c", _WRITER, str(path)],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    flushed = 0
    try:
        while flushed < 40:
            line = proc.stdout.readline()
            assert line, f"writer stopped early: {proc.stderr.read()}"
            flushed = int(line)
        proc.kill()
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()
        proc.stderr.close()
    log = read_log(path)
    assert not log.complete
    assert len(log.messages) >= flushed
    assert [m.timestamp for m in log.messages] == pytest.approx(
        [0.1 * k for k in range(len(log.messages))]
    )
    records = log.records()
    assert [type(r).__name__ for r in records[:3]] == ["OdometryReading", "LedObservation", "Event"]
    assert all(not isinstance(r, dict) for r in records)
    assert all(np.isnan(r.pixels[1]).all() for r in log.records("/topic/1"))


def test_cut_anywhere_gives_a_prefix(tmp_path: Path) -> None:
    whole = tmp_path / "whole.mcap"
    entries = sample_records()
    write_log(whole, entries)
    data = whole.read_bytes()
    full = read_log(whole)
    cut = tmp_path / "cut.mcap"
    previous = 0
    # Every third byte (each 9-byte record header is cut in three places) and every byte of
    # the magic, the header and the closing footer.
    ends = sorted({*range(1, 64), *range(64, len(data), 3), *range(len(data) - 40, len(data))})
    for end in ends:
        cut.write_bytes(data[:end])
        log = read_log(cut)
        n = len(log.messages)
        assert not log.complete, end
        assert log.messages == full.messages[:n], end
        assert n >= previous, end
        assert log.unread_bytes <= end
        previous = n
    assert previous == len(entries)


def test_not_mcap_raises_value_error(tmp_path: Path) -> None:
    text = tmp_path / "notes.txt"
    text.write_text("not a log at all\n")
    with pytest.raises(ValueError, match=r"notes\.txt.*not an MCAP"):
        read_log(text)
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    with pytest.raises(ValueError, match=r"empty\.mcap.*empty"):
        read_log(empty)
    with pytest.raises(FileNotFoundError, match=r"missing\.mcap"):
        read_log(tmp_path / "missing.mcap")


def test_corrupt_message_raises_value_error(tmp_path: Path) -> None:
    path = tmp_path / "bad.mcap"
    write_log(path, [("/x", {"a": "ZZZZ"}, 1.0)])
    data = path.read_bytes().replace(b'{"a":"ZZZZ"}', b'{"a":"ZZZZ"]')
    path.write_bytes(data)
    with pytest.raises(ValueError, match=r"bad\.mcap.*'/x'.*not JSON"):
        read_log(path)


def test_log_message_decode(tmp_path: Path) -> None:
    path = tmp_path / "one.mcap"
    tilt = TiltReading(2.0, 0.001, 0.002)
    write_log(path, [("/tilt", tilt, 2.0)])
    (msg,) = read_log(path).messages
    assert msg.decode() == tilt == decode(msg.data)


def test_mcap_reader_reads_a_closed_log(tmp_path: Path) -> None:
    path = tmp_path / "closed.mcap"
    entries = sample_records()
    write_log(path, entries)
    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        assert summary.statistics.message_count == len(entries)
        assert summary.statistics.chunk_count == 0
        assert {s.encoding for s in summary.schemas.values()} == {"jsonschema"}
        assert {c.message_encoding for c in summary.channels.values()} == {"json"}
        topics = [channel.topic for _, channel, _ in reader.iter_messages(log_time_order=False)]
    assert topics == [e[0] for e in entries]
