"""``twin devices``: open every device of a rig file and say what it is."""

from __future__ import annotations

import argparse
from pathlib import Path

from rich.console import Console
from rich.markup import escape
from rich.table import Table


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``devices`` subcommand."""
    p = sub.add_parser(
        "devices",
        help="connect to every device of a rig file and print what it found",
        description=(
            "Open each device of a rig file in turn: the total station (name, serial "
            "number), each robot (type, battery), each camera (resolution, frame rate); "
            "then blink each child's LEDs in front of every camera and count the LEDs "
            "found. Closes them all; moves no robot. Exit code 0 when every device "
            "answered, 1 when one did not, 2 for a bad rig file."
        ),
    )
    p.add_argument("rig", type=Path, help="rig file (.toml)")
    p.add_argument(
        "--no-blink", action="store_true", help="do not switch the LEDs in front of the cameras"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Probe; exit code 0, 1 when a device did not answer, 2 for a bad rig file."""
    from twin.drivers.probe import DeviceReport, probe_rig
    from twin.drivers.rig_file import RigFileError, load_rig_file

    console = Console(highlight=False, soft_wrap=True)
    try:
        rig = load_rig_file(args.rig)
    except RigFileError as exc:
        console.print(str(exc), markup=False)
        return 2
    table = Table(title=f"devices of {args.rig}")
    for col in ("device", "kind", "where", "answer"):
        table.add_column(col)

    def show(r: DeviceReport) -> None:
        facts = "; ".join(f"{k} {v}" for k, v in r.facts.items())
        console.print(f"{'ok ' if r.ok else 'NO '} {r.kind} {r.device}: {facts}", markup=False)
        answer = ("" if r.ok else "[red]failed[/red] ") + escape(facts)
        table.add_row(escape(r.device), r.kind, escape(r.where), answer)

    reports = probe_rig(rig, show, blink=not args.no_blink)
    console.print(table)
    return 0 if all(r.ok for r in reports) else 1
