"""``twin replay``: a run's results, camera files, figures and report again from its log."""

from __future__ import annotations

import argparse
from pathlib import Path

from rich.console import Console

from twin.cli import arguments


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``replay`` subcommand."""
    p = sub.add_parser(
        "replay",
        help="compute a run's results again from its log (twin or real hardware)",
        description=(
            "Read a run's log.mcap (whole, or cut short by a kill) and write results.json, "
            "cameras/, figures/ and report.md again, as the run did. With --model opencv "
            "each visit is calibrated again, from the same points, in OpenCV's model. The "
            "whole campaign is adjusted at once as twin run does (--adjust). The run's "
            "scenario is the file its log names, looked for where it was, beside the log "
            "and in the working folder, and checked against the digest the log records. "
            "Reads the logs of campaigns (twin run), not those of twin check. Exit "
            "code 0; 1 when the log holds no calibration; 2 for bad input."
        ),
    )
    p.add_argument("log", type=Path, help="the run's log.mcap")
    p.add_argument(
        "--out", type=Path, help="output folder, empty or new (default: beside the log, replay/)"
    )
    p.add_argument(
        "--model",
        choices=("tsai", "opencv"),
        default="tsai",
        help="tsai: the campaign's calibrations as logged (default); opencv: fitted again",
    )
    p.add_argument(
        "--scenario",
        type=Path,
        help="the run's scenario, for the figures (default: the file the log names); one "
        "whose digest is not the log's is refused",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="use a scenario whose digest is not the one the log records",
    )
    p.add_argument(
        "--adjust",
        choices=("shared", "per_visit", "none"),
        help="adjust the whole campaign at once: a camera visited twice is one camera "
        "(shared: the default with --model tsai, as twin run does), or one per visit tied "
        "through control points (per_visit); none: the sequential results only (the "
        "default with --model opencv)",
    )
    p.add_argument("--no-report", action="store_true", help="skip the figures and report.md")
    p.add_argument(
        "--foxglove",
        type=Path,
        metavar="OUT.mcap",
        help="write OUT.mcap instead of the results: the log's records with Foxglove's "
        "channels (3D scene, frames, log, tracks) derived from them, as twin run writes "
        "them today; for a log of any version (what it lacks is said). The site and route "
        "come from the run's scenario, left out when it is not found",
    )
    arguments.add_overwrite(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Replay; exit code 0, 1 without calibrations, 2 for bad input."""
    from twin.cli.run import print_results
    from twin.run.replay import replay_log
    from twin.scenario import ScenarioError

    console = Console(highlight=False, soft_wrap=True)
    if not args.log.is_file():
        console.print(f"[red]error:[/red] {args.log}: no such log file", highlight=False)
        return 2
    if args.foxglove is not None:
        return _foxglove(args, console)
    out = args.out or args.log.parent / "replay"
    try:
        results = replay_log(
            args.log,
            out,
            model=args.model,
            scenario=args.scenario,
            report=not args.no_report,
            overwrite=args.overwrite,
            adjust={None: "auto", "none": None}.get(args.adjust, args.adjust),
            force=args.force,
            warn=lambda text: console.print(f"warning: {text}", markup=False),
        )
    except (ValueError, ScenarioError) as exc:
        console.print(f"error: {exc}", markup=False)
        return 2
    print_results(results, console)
    console.print(f"written in {out}")
    return 0 if results["calibrations"] else 1


def _foxglove(args: argparse.Namespace, console: Console) -> int:
    """``--foxglove``: the log with Foxglove's channels; exit code 0, 2 for bad input."""
    from twin.run.replay import foxglove_log
    from twin.scenario import ScenarioError

    try:
        counts = foxglove_log(
            args.log,
            args.foxglove,
            scenario=args.scenario,
            force=args.force,
            overwrite=args.overwrite,
            warn=lambda text: console.print(f"warning: {text}", markup=False),
        )
    except (ValueError, ScenarioError) as exc:
        console.print(f"error: {exc}", markup=False)
        return 2
    for topic, n in counts.items():
        console.print(f"{topic}: {n}", markup=False)
    console.print(f"written {args.foxglove}", markup=False)
    return 0
