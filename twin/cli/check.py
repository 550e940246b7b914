"""``twin check``: are the calibrated cameras still where their calibrations say?"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.live import Live
from rich.markup import escape
from rich.table import Table

from twin.campaign.check import (
    DEFAULT_FALSE_ALARM_RATE,
    DEFAULT_STOPS,
    MAX_STOPS,
    MIN_PIXEL_SIGMA,
    MIN_STOPS,
)
from twin.campaign.strategy import Strategy
from twin.cli import arguments
from twin.cli.live_status import LiveStatus
from twin.cli.scene import load_or_report
from twin.interruption import EXIT_INTERRUPTED, interruption_reason


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``check`` subcommand."""
    p = sub.add_parser(
        "check",
        help="check whether calibrated cameras moved, and re-pose those that did",
        description=(
            "For each camera in DIR (the cameras/ folder a `twin run` wrote; its latest "
            "calibration), the child stops a few times in the camera's view: from the "
            "parent's first station (the calibration's W) if it sees the camera, else from "
            "the camera's visit station, reached by CPS. The LED pixels are compared with "
            "the calibrated camera's projections of the measured LEDs by a chi-square test "
            "at the false-alarm rate; a moved camera is re-posed from the same points, its "
            "intrinsics kept. Prints a table and writes OUT/check.json, OUT/cameras/ (the "
            "re-posed cameras) and OUT/log.mcap. Exit code 0 when every camera was checked "
            "and none moved; 1 when one moved or could not be checked; 2 for bad input "
            "(nothing written); 130 when interrupted."
        ),
    )
    p.add_argument("scenario", type=Path, help="scenario file (.toml or .yaml)")
    p.add_argument(
        "--cameras",
        type=Path,
        required=True,
        metavar="DIR",
        help="the cameras/ folder a run wrote (NAME_visitK.json: the latest of each camera "
        "is checked)",
    )
    p.add_argument(
        "--rig",
        type=Path,
        metavar="RIG.toml",
        help="check on the real devices (or the emulators) of this rig file instead of the "
        "twin; the parent must stand at the calibration's first station",
    )
    p.add_argument(
        "--fidelity",
        choices=("render", "geometric"),
        help="the twin's fidelity, as twin run's (default: render)",
    )
    p.add_argument(
        "--seed",
        type=arguments.seed,
        help="the twin's seed, as twin run's (default: the scenario's); the check draws "
        "its noise from streams of its own",
    )
    p.add_argument(
        "--stops",
        type=_stops,
        default=DEFAULT_STOPS,
        help=f"the child's stops per camera, {MIN_STOPS} to {MAX_STOPS}, 4 LED points each "
        f"(default: {DEFAULT_STOPS})",
    )
    p.add_argument(
        "--false-alarm-rate",
        type=_probability,
        default=DEFAULT_FALSE_ALARM_RATE,
        metavar="ALPHA",
        help="probability that an unmoved camera is called moved (default: "
        f"{DEFAULT_FALSE_ALARM_RATE:g})",
    )
    p.add_argument(
        "--min-pixel-sigma",
        type=arguments.positive_float,
        default=MIN_PIXEL_SIGMA,
        metavar="PX",
        help="least standard deviation of an LED's pixel coordinate the test assumes, px "
        f"(default: {MIN_PIXEL_SIGMA:g}, what the detector achieves on the twin's images; "
        "more for a camera with worse centroids)",
    )
    arguments.add_strategy(p)
    p.add_argument(
        "--out",
        type=Path,
        help="output folder, empty or new (default: out/SCENARIO-check)",
    )
    arguments.add_overwrite(p)
    p.set_defaults(func=run)


_stops = arguments.number_in(int, MIN_STOPS, MAX_STOPS, why="one stop's LEDs stand on one line")
"""A number of stops from :data:`MIN_STOPS` to :data:`MAX_STOPS`."""

_probability = arguments.number_in(float, 0.0, 1.0, exclusive=True)
"""A probability strictly between 0 and 1."""


def run(args: argparse.Namespace) -> int:
    """Check; exit code 0 (all checked, none moved), 1 (one moved or not checked), 2 for
    bad input, 130 when interrupted."""
    from twin.campaign.strategies import strategy_for
    from twin.run.run_cameras import CamerasFolderError, latest_cameras

    console = Console(highlight=False, soft_wrap=True)
    sc = load_or_report(args.scenario, console)
    if sc is None:
        return 2
    # Built once here: the name is known (argparse's choices, the scenario's checks).
    strategy = strategy_for(sc, args.strategy)
    if args.rig is not None:
        twin_only = (("--fidelity", args.fidelity), ("--seed", args.seed))
        refused = [f for f, given in twin_only if given is not None]
        if refused:
            console.print(f"[red]error:[/red] {', '.join(refused)} apply to the twin, not to --rig")
            return 2
    out = args.out or Path("out") / f"{sc.name}-check"
    try:
        latest_cameras(args.cameras, sc)  # a bad folder is refused before the twin loads
    except CamerasFolderError as exc:
        console.print(f"[red]error:[/red] {escape(str(exc))}")
        return 2
    try:
        with Live(console=console, refresh_per_second=4, transient=True) as live:
            results = _check(
                args,
                sc,
                out,
                strategy,
                LiveStatus(
                    live,
                    {"reference": "first station", "station": "visit station"},
                    calibrated=False,
                ),
                console,
            )
    except (CamerasFolderError, ValueError) as exc:
        console.print(f"[red]error:[/red] {escape(str(exc))}")
        return 2
    except KeyboardInterrupt as exc:
        log = out / "log.mcap"
        kept = f"the log of the check so far is {log}" if log.exists() else "nothing was written"
        console.print(f"interrupted ({interruption_reason(exc)}): {kept}")
        return EXIT_INTERRUPTED
    if results is None:
        return 2
    print_check(results, console)
    console.print(f"written in {out}")
    moved = any(c["moved"] for c in results["cameras"].values())
    return 1 if moved or results["unchecked"] else 0


def _check(
    args: argparse.Namespace,
    sc: Any,
    out: Path,
    strategy: Strategy,
    display: Any,
    console: Console,
) -> dict[str, Any] | None:
    """The check in the twin or on the rig file's devices; None (the error shown) for a
    bad rig file or a device that cannot be opened."""
    common = {
        "stops": args.stops,
        "false_alarm_rate": args.false_alarm_rate,
        "min_pixel_sigma": args.min_pixel_sigma,
        "progress": display,
        "strategy": strategy,
        "overwrite": args.overwrite,
    }
    if args.rig is None:
        from twin.run.runner import check_scenario

        fidelity = args.fidelity or "render"
        return check_scenario(sc, args.cameras, out, fidelity=fidelity, seed=args.seed, **common)
    from twin.drivers.build import DeviceConnectError
    from twin.drivers.rig_file import RigFileError
    from twin.run.hardware_run import check_on_rig

    try:
        return check_on_rig(sc, args.rig, args.cameras, out, **common)
    except RigFileError as exc:
        console.print(str(exc), markup=False)
    except (DeviceConnectError, ImportError) as exc:
        console.print(f"[red]error:[/red] {escape(str(exc))}")
    return None


def _fmt(value: float | None, spec: str) -> str:
    return "-" if value is None or not math.isfinite(value) else format(value, spec)


def print_check(results: dict[str, Any], console: Console) -> None:
    """The verdicts as a table (camera, verdict, shift and turn with the largest standard
    deviation of their components, chi-square and threshold, where the data were taken),
    and the cameras not checked."""
    alpha = results["false_alarm_rate"]
    table = Table(
        title=f"{results['scenario']}: {results['stops']} stops per camera, false-alarm "
        f"rate {alpha:g}"
    )
    for col in ("camera", "verdict", "shift mm", "turn deg", "chi2 / dof", "threshold", "from"):
        table.add_column(col, justify="left" if col in ("camera", "from") else "right")
    for name, c in results["cameras"].items():
        shift_std = max(c.get("shift_std_mm") or [math.nan])
        turn_std = max(c.get("turn_std_deg") or [math.nan])
        verdict = "[red]moved[/red]" if c["moved"] else "[green]unchanged[/green]"
        table.add_row(
            name,
            verdict,
            f"{_fmt(c['shift_mm'], '.1f')}±{_fmt(shift_std, '.1f')}",
            f"{_fmt(c['turn_deg'], '.3f')}±{_fmt(turn_std, '.3f')}",
            f"{c['chi2']:.1f}/{c['dof']}",
            f"{c['threshold']:.1f}",
            c["station"].replace(" station", ""),
        )
    console.print(table)
    for name, c in results["cameras"].items():
        if not c["calibration_covariance"]:
            console.print(
                f"{name}: {c['calibration']} holds no covariance: its calibration was taken as "
                "exact, so its own error counts as a move"
            )
        if c["moved"] and c["reposed"] is None:
            console.print(f"{name}: moved, but not re-posed: {c.get('repose_error', '')}")
    for name, why in results["unchecked"].items():
        console.print(f"not checked: {name}: {why}")
    if results["failures"]:
        console.print("failures: " + ", ".join(f"{k} {v}" for k, v in results["failures"].items()))
