"""What ``twin run --live`` costs: the hall at the geometric fidelity without the server,
with it and no client, and with it and a client that reads slowly (one message every
``--client-delay`` s), in rounds (their order turning), the median over the rounds.

Run: ``.venv/bin/python benchmarks/bench_foxglove_live.py [--rounds N] [--scenario FILE]``

Reports each run's wall time, the medians and the ratios to the run without the server,
the messages the server was offered, sent and dropped, and whether every run gave the
same calibrations.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import threading
import time
from pathlib import Path

from rich.console import Console
from rich.table import Table
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

import twin.sim  # noqa: F401  # isort: skip
from twin.record.foxglove.live import LiveServer
from twin.run.runner import run_scenario

ROOT = Path(__file__).resolve().parents[1]
HALL = ROOT / "scenarios" / "paper_hall.toml"
MODES = ("off", "live, no client", "live, slow client")


def slow_client(port: int, delay: float, subscribed: threading.Event) -> None:
    """Subscribe to every channel, then read one message every ``delay`` s until closed."""
    with connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"]) as ws:
        try:
            for frame in ws:
                if isinstance(frame, str) and json.loads(frame)["op"] == "advertise":
                    channels = json.loads(frame)["channels"]
                    subs = [{"id": c["id"], "channelId": c["id"]} for c in channels]
                    ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                    subscribed.set()
                time.sleep(delay)
        except ConnectionClosed:
            pass


def one_run(
    scenario: Path, mode: str, folder: Path, delay: float
) -> tuple[float, float, dict, tuple]:
    """Wall time, s, CPU time of this process, s, results and the server's (offered, sent,
    dropped) of one run."""
    server = LiveServer(port=0) if mode != "off" else None
    client = None
    if server is not None and mode == "live, slow client":
        subscribed = threading.Event()
        client = threading.Thread(target=slow_client, args=(server.port, delay, subscribed))
        client.start()
        subscribed.wait(10)
        while not server.has_clients():
            time.sleep(0.01)
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        results = run_scenario(scenario, folder, fidelity="geometric", report=False, live=server)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    finally:
        if server is not None:
            server.close()
        if client is not None:
            client.join(30)
    counts = (server.offered, server.sent, server.dropped) if server else (0, 0, 0)
    return wall, cpu, results, counts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--scenario", type=Path, default=HALL)
    parser.add_argument("--client-delay", type=float, default=0.05)
    args = parser.parse_args()
    console = Console()
    walls: dict[str, list[float]] = {m: [] for m in MODES}
    cpus: dict[str, list[float]] = {m: [] for m in MODES}
    counts: dict[str, tuple] = {}
    calibrations = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.rounds):
            order = MODES[k % 3 :] + MODES[: k % 3]
            for mode in order:
                folder = Path(tmp) / f"{k}-{MODES.index(mode)}"
                wall, cpu, results, counts[mode] = one_run(
                    args.scenario, mode, folder, args.client_delay
                )
                walls[mode].append(wall)
                cpus[mode].append(cpu)
                calibrations.append(results["calibrations"])
                console.print(f"round {k}, {mode}: {wall:.2f} s, sent/dropped {counts[mode][1:]}")
    base = statistics.median(walls["off"])
    table = Table(title=f"{args.scenario.name}, geometric: twin run with and without --live")
    for col in ("", "wall, median", "ratio", "CPU, median", "offered", "sent", "dropped"):
        table.add_column(col, justify="right")
    for mode in MODES:
        w = statistics.median(walls[mode])
        offered, sent, dropped = counts[mode]
        table.add_row(
            mode,
            f"{w:.2f} s",
            f"{w / base:.3f}",
            f"{statistics.median(cpus[mode]):.2f} s",
            str(offered),
            str(sent),
            str(dropped),
        )
    console.print(table)
    same = all(c == calibrations[0] for c in calibrations)
    console.print(f"every run gave the same calibrations: {same}")


if __name__ == "__main__":
    main()
