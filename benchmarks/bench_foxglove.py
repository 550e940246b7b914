"""What the Foxglove channels cost: ``twin run`` with and without them, in pairs (their
order alternating), the median over the pairs: the hall at the geometric fidelity, or, with
``--fidelity render``, the smoke room at the render fidelity (its channels then hold each
data stop's camera image).

Run: ``.venv/bin/python benchmarks/bench_foxglove.py [--pairs N] [--fidelity F]
[--scenario FILE]`` (the render pairs of the smoke room take about 40 s a run).

Reports each run's wall time, CPU time and log size, the medians and the ratios, checks
that both runs of a pair give the same calibrations, and lists the Foxglove channels of
the last run's log with their message counts and bytes.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from collections import Counter
from pathlib import Path

from mcap.reader import make_reader
from rich.console import Console
from rich.table import Table

import twin.sim  # noqa: F401  # isort: skip
import twin.run.campaign_run as campaign_run
from twin.run.runner import run_scenario

ROOT = Path(__file__).resolve().parents[1]
HALL = ROOT / "scenarios" / "paper_hall.toml"
SMOKE = ROOT / "scenarios" / "smoke.toml"
DEFAULT_SCENARIO = {"geometric": HALL, "render": SMOKE}
"""The scenario of each fidelity, unless ``--scenario`` says: the hall's render run lasts
too long to be paired five times."""


def one_run(
    scenario: Path, fidelity: str, foxglove: bool, folder: Path
) -> tuple[float, int, dict, float]:
    """Wall time, s, log size, bytes, results and CPU time of this process, s, of one run
    (with or without the channels)."""
    real = campaign_run.FoxgloveStream
    if not foxglove:
        campaign_run.FoxgloveStream = lambda sc: None  # type: ignore[assignment,misc]
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        results = run_scenario(scenario, folder, fidelity=fidelity, report=False)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    finally:
        campaign_run.FoxgloveStream = real  # type: ignore[misc]
    return wall, (folder / "log.mcap").stat().st_size, results, cpu


def channel_counts(log: Path) -> tuple[Counter, Counter]:
    """Messages and their bytes by (topic, schema) of the Foxglove channels of a log."""
    counts: Counter = Counter()
    sizes: Counter = Counter()
    with open(log, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            if channel.message_encoding == "protobuf":
                counts[channel.topic, schema.name] += 1
                sizes[channel.topic, schema.name] += len(message.data)
    return counts, sizes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--pairs", type=int, default=5)
    parser.add_argument("--fidelity", default="geometric")
    parser.add_argument("--scenario", type=Path, default=None)
    args = parser.parse_args()
    if args.scenario is None:
        args.scenario = DEFAULT_SCENARIO.get(args.fidelity, HALL)
    console = Console()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.pairs):
            order = (True, False) if k % 2 == 0 else (False, True)
            pair = {}
            for on in order:
                folder = Path(tmp) / f"{k}-{'on' if on else 'off'}"
                pair[on] = one_run(args.scenario, args.fidelity, on, folder)
            same = pair[True][2]["calibrations"] == pair[False][2]["calibrations"]
            rows.append((pair[True][:2], pair[False][:2], same, pair[True][3], pair[False][3]))
            walls = f"{pair[True][0]:.2f} s / {pair[False][0]:.2f} s"
            console.print(f"pair {k}: with / without {walls}; same results: {same}")
        counts, sizes = channel_counts(Path(tmp) / f"{args.pairs - 1}-on" / "log.mcap")
    table = Table(title=f"{args.scenario.name}, {args.fidelity}: with and without Foxglove")
    columns = ("pair", "with, s", "without, s", "with, MB", "without, MB", "same results")
    for column in (*columns, "with, CPU s", "without, CPU s"):
        table.add_column(column)
    for k, ((w_on, s_on), (w_off, s_off), same, c_on, c_off) in enumerate(rows):
        table.add_row(
            str(k),
            f"{w_on:.2f}",
            f"{w_off:.2f}",
            f"{s_on / 1e6:.2f}",
            f"{s_off / 1e6:.2f}",
            str(same),
            f"{c_on:.2f}",
            f"{c_off:.2f}",
        )
    on = statistics.median(r[0][0] for r in rows)
    off = statistics.median(r[1][0] for r in rows)
    cpu_on = statistics.median(r[3] for r in rows)
    cpu_off = statistics.median(r[4] for r in rows)
    table.add_row(
        "median", f"{on:.2f}", f"{off:.2f}", "", "", "", f"{cpu_on:.2f}", f"{cpu_off:.2f}"
    )
    console.print(table)
    size_on = statistics.median(r[0][1] for r in rows)
    size_off = statistics.median(r[1][1] for r in rows)
    console.print(
        f"wall time with / without: {on / off:.3f}; CPU time: {cpu_on / cpu_off:.3f}; "
        f"log size: {size_on / 1e6:.2f} MB / {size_off / 1e6:.2f} MB = {size_on / size_off:.3f}"
    )
    channels = Table(title="Foxglove channels of the log")
    channels.add_column("topic")
    channels.add_column("schema")
    channels.add_column("messages")
    channels.add_column("kB")
    for (topic, schema), n in sorted(counts.items()):
        channels.add_row(topic, schema, str(n), f"{sizes[topic, schema] / 1e3:.1f}")
    console.print(channels)


if __name__ == "__main__":
    main()
