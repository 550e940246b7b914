"""``twin run --live``: the log's Foxglove channels served over Foxglove's WebSocket protocol
while the campaign runs, read by a WebSocket client; the run's results and log are the same
without the server, and the server stops with the run."""

from __future__ import annotations

import json
import socket
import struct
import threading
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from tests.twin.record.test_foxglove import run_records, run_results
from twin.cli import main
from twin.record.foxglove import TOPICS
from twin.record.foxglove.live import LiveServer
from twin.run.runner import run_scenario

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"
SUBPROTOCOL = "foxglove.sdk.v1"
"""The SDK's name for Foxglove's WebSocket protocol (formerly ``foxglove.websocket.v1``)."""
MESSAGE_DATA = 0x01


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def refused(port: int) -> bool:
    """Whether nothing listens on ``port`` of this machine any more."""
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) != 0


class Client(threading.Thread):
    """A Foxglove WebSocket client that connects (retrying until the server is up),
    subscribes to every advertised channel and keeps what it receives until the server
    closes the connection."""

    def __init__(self, port: int) -> None:
        super().__init__(daemon=True)
        self.port = port
        self.advertised: dict[int, dict[str, Any]] = {}
        self.received: dict[str, list[tuple[int, bytes]]] = defaultdict(list)
        self.subscribed = threading.Event()

    def run(self) -> None:
        deadline = time.monotonic() + 60
        while True:
            try:
                ws = connect(f"ws://127.0.0.1:{self.port}", subprotocols=[SUBPROTOCOL])
                break
            except OSError:
                if time.monotonic() > deadline:
                    return
                time.sleep(0.02)
        topic_of: dict[int, str] = {}
        with ws:
            try:
                for frame in ws:
                    if isinstance(frame, str):
                        op = json.loads(frame)
                        if op["op"] == "advertise":
                            subs = []
                            for ch in op["channels"]:
                                self.advertised[ch["id"]] = ch
                                topic_of[ch["id"]] = ch["topic"]
                                subs.append({"id": ch["id"], "channelId": ch["id"]})
                            ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                            self.subscribed.set()
                    elif frame[0] == MESSAGE_DATA:
                        sub, log_time = struct.unpack_from("<IQ", frame, 1)
                        self.received[topic_of[sub]].append((log_time, frame[13:]))
            except ConnectionClosed:
                pass


def log_foxglove(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    """A log's Foxglove messages by topic: (log time ns, protobuf bytes)."""
    out: dict[str, list] = defaultdict(list)
    with open(path, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages():
            if channel.message_encoding == "protobuf":
                out[channel.topic].append((message.log_time, message.data))
    return dict(out)


@pytest.fixture(scope="module")
def live_run(tmp_path_factory) -> tuple[Path, int, Client, str]:
    """A smoke campaign with ``twin run --live`` on a free port and a client reading it."""
    out = tmp_path_factory.mktemp("live") / "run"
    port = free_port()
    client = Client(port)
    client.start()
    code = main(
        [
            "run",
            str(SMOKE),
            "--fidelity",
            "geometric",
            "--seed",
            "5",
            "--no-report",
            "--out",
            str(out),
            "--live",
            "--port",
            str(port),
        ]
    )
    client.join(timeout=30)
    return out, code, client, port


@pytest.fixture(scope="module")
def plain_run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("plain")
    run_scenario(SMOKE, out, fidelity="geometric", report=False, seed=5)
    return out


def test_a_client_is_advertised_every_channel_with_its_schema(live_run):
    _, code, client, _ = live_run
    assert code == 0
    advertised = {ch["topic"]: ch for ch in client.advertised.values()}
    # The children's tracks are advertised from their first message on.
    tracks = {
        f"/foxglove/track/{c}_{w}": "foxglove.PosesInFrame"
        for c in ("child1", "child2")
        for w in ("estimate", "truth")
    }
    assert {t: ch["schemaName"] for t, ch in advertised.items()} == {**TOPICS, **tracks}
    assert all(ch["encoding"] == "protobuf" for ch in advertised.values())


def test_the_client_receives_the_logs_messages_as_the_campaign_runs(live_run):
    out, _, client, _ = live_run
    logged = log_foxglove(out / "log.mcap")
    assert sum(len(v) for v in client.received.values()) > 100
    assert len(client.received) >= 5
    for topic, got in client.received.items():
        # What came before the client subscribed is not sent again; the rest is the log's.
        assert got == logged[topic][-len(got) :], topic


def test_the_server_stops_with_the_run(live_run, capsys):
    _, _, client, port = live_run
    assert not client.is_alive()  # the server closed the connection
    assert refused(port)


def test_the_results_and_the_log_are_the_same_without_the_server(live_run, plain_run):
    out = live_run[0]
    assert run_results(out) == run_results(plain_run)
    assert run_records(out) == run_records(plain_run)
    assert log_foxglove(out / "log.mcap") == log_foxglove(plain_run / "log.mcap")


class StalledChannel:
    """A channel whose sending waits until ``go`` is set: a server that cannot send."""

    def __init__(self) -> None:
        self.go = threading.Event()
        self.logged = 0

    def has_sinks(self) -> bool:
        return True

    def log(self, data: bytes, log_time: int) -> None:
        self.go.wait(10)
        self.logged += 1


def test_a_full_queue_drops_and_counts_without_waiting():
    from twin.record.foxglove.stream import LOG, FoxgloveStream

    stalled = StalledChannel()
    with LiveServer(port=0, queue_size=5) as server:
        server._channels[LOG] = stalled
        message = FoxgloveStream().unreadable("/x", 1.0, ValueError("bad"))[0][1]
        start = time.perf_counter()
        server.offer([(LOG, message)] * 1000, 1.0)
        assert time.perf_counter() - start < 1.0  # the run never waits for the server
        assert server.offered == 1000
        # One message is being sent, five wait in the queue, the others are dropped.
        assert 994 <= server.dropped <= 995
        stalled.go.set()
    assert stalled.logged == server.sent == 1000 - server.dropped


def test_a_port_in_use_is_named_and_nothing_is_written(tmp_path, capsys):
    with LiveServer(port=0) as taken:
        out = tmp_path / "run"
        args = ["run", str(SMOKE), "--fidelity", "geometric", "--out", str(out)]
        code = main([*args, "--live", "--port", str(taken.port)])
    assert code == 2
    said = capsys.readouterr().out
    assert f"--port {taken.port}" in said
    assert "in use" in said
    assert not out.exists()


def test_port_without_live_is_refused(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["run", str(SMOKE), "--fidelity", "geometric", "--out", str(out), "--port", "1"])
    assert code == 2
    assert "--port and --host apply to --live only" in capsys.readouterr().out
    assert not out.exists()


def test_emulate_serves_the_worlds_truth_live_and_stops(tmp_path):
    port = free_port()
    client = Client(port)
    client.start()
    rig = tmp_path / "rig.toml"
    args = ["emulate", str(SMOKE), "--duration", "3", "--rig-out", str(rig)]
    assert main([*args, "--live", "--port", str(port)]) == 0
    client.join(timeout=30)
    assert {ch["topic"] for ch in client.advertised.values()} == set(TOPICS)
    tf = [data for _, data in client.received["/foxglove/tf"]]
    for robot in ("parent", "child1", "child2"):
        assert sum(f"{robot}/truth".encode() in data for data in tf) >= 3, robot
    assert any(b"instrument/truth" in data for data in tf)
    assert refused(port)
