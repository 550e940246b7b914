"""``twin run``: the whole calibration campaign of a scenario, in the twin."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from rich import box
from rich.console import Console
from rich.live import Live
from rich.markup import escape
from rich.table import Table

from twin.campaign.strategies import strategy_for
from twin.campaign.strategy import Strategy
from twin.cli import arguments, live_server
from twin.cli.live_status import LiveStatus
from twin.cli.scene import load_or_report
from twin.interruption import EXIT_INTERRUPTED, interruption_reason
from twin.outputs import OutputError, check_file_target

if TYPE_CHECKING:
    from twin.record.foxglove.live import LiveServer


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``run`` subcommand."""
    p = sub.add_parser(
        "run",
        help="run the calibration campaign of a scenario in the twin (or on a rig)",
        description=(
            "Run the paper's calibration campaign on a scenario: reference data sets from the "
            "first station, CPS travel along the route, a calibration at every visit. In the "
            "twin, or with --rig on real devices (or their emulators). Writes "
            "DIR/log.mcap (every reading, as it arrives), DIR/results.json, DIR/cameras/, "
            "DIR/figures/ and DIR/report.md. Exit code 0 when every visit of the scenario "
            "gave a calibration; 1 when one did not (the dropped visits are listed with "
            "why); 2 for bad input (nothing written: a rig file that does not fit the scenario, a "
            "folder another run is writing) or a device that cannot be opened (the log of "
            "the attempt is kept); 130 when interrupted (Ctrl-C, SIGTERM: every robot is "
            "stopped, the log so far is kept)."
        ),
    )
    p.add_argument("scenario", type=Path, help="scenario file (.toml or .yaml)")
    p.add_argument(
        "--fidelity",
        choices=("render", "geometric"),
        help="render: robots driven in MuJoCo, rendered images, LED detection (default); "
        "geometric: robots placed with a stopping error, LEDs projected with detection noise",
    )
    p.add_argument(
        "--rig",
        type=Path,
        metavar="RIG.toml",
        help="run on the real devices (or the emulators) of this rig file instead of the "
        "twin; the scenario still gives the map, the cameras, the route and the visits. "
        "Ctrl-C stops every robot and keeps the log",
    )
    p.add_argument(
        "--seed",
        type=arguments.seed,
        help="root seed of the run, 0 to 2^63 - 1 (default: the scenario's)",
    )
    arguments.add_strategy(p)
    p.add_argument(
        "--out",
        type=Path,
        help="output folder, empty or new (default: out/SCENARIO-FIDELITY)",
    )
    arguments.add_overwrite(p)
    p.add_argument(
        "--no-noise", action="store_true", help="switch every noise source off (default: on)"
    )
    p.add_argument(
        "--no-report",
        action="store_true",
        help="skip the figures and report.md (default: write them)",
    )
    live_server.add_live(
        p,
        "the log's Foxglove channels while the campaign runs (the results and the log are "
        "the same without the server)",
    )
    p.add_argument(
        "--video",
        type=Path,
        metavar="FILE.mp4",
        help="after the run, render a video of it from its log: a camera above the site "
        "following the group, the route and the cameras' frustums (as built green, as "
        "calibrated blue) drawn; in the twin only",
    )
    p.add_argument(
        "--video-period",
        type=arguments.number_in(float, 0.0, exclusive=True, unit="s"),
        metavar="S",
        help="seconds of campaign time per frame of --video (default: 1 s, or longer so "
        "that the video lasts at most 2 minutes at 10 frames per second)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run; exit code 0, 1 when a visit of the scenario was dropped (no calibration), 2 for
    bad input, 130 when interrupted."""
    console = Console(highlight=False, soft_wrap=True)
    sc = load_or_report(args.scenario, console)
    if sc is None:
        return 2
    # Built once here: the name is known (argparse's choices, the scenario's checks).
    strategy = strategy_for(sc, args.strategy)
    if args.rig is not None:
        refused = [
            f
            for f, given in (("--fidelity", args.fidelity), ("--seed", args.seed))
            if given is not None
        ]
        refused += ["--no-noise"] if args.no_noise else []
        if refused:
            console.print(f"[red]error:[/red] {', '.join(refused)} apply to the twin, not to --rig")
            return 2
    if live_server.refused(args, console):
        return 2
    if args.video_period is not None and args.video is None:
        console.print("[red]error:[/red] --video-period applies to --video only")
        return 2
    if args.video is not None:
        if args.rig is not None:
            console.print("[red]error:[/red] --video applies to the twin, not to --rig")
            return 2
        check_file_target(args.video, "--video")
        if args.video.suffix.lower() != ".mp4":
            raise OutputError(
                f"--video {args.video}: the video is written as MP4; give a .mp4 file"
            )
    fidelity = args.fidelity or "render"
    where = "rig" if args.rig is not None else fidelity
    out = args.out or Path("out") / f"{sc.name}-{where}"
    how = f"on the devices of {args.rig}" if args.rig else f"at the {fidelity} fidelity"
    console.print(
        f"running [bold]{sc.name}[/bold] {how} with the {strategy.name} strategy into {out}"
    )
    server = live_server.start_live(args, console) if args.live else None
    if args.live and server is None:
        return 2
    try:
        with Live(console=console, refresh_per_second=4, transient=True) as live:
            if args.rig is not None:
                results = _run_on_rig(args, sc, out, strategy, LiveStatus(live), console, server)
                if results is None:
                    return 2
            else:
                from twin.run.runner import run_scenario

                results = run_scenario(
                    sc,
                    out,
                    fidelity=fidelity,
                    seed=args.seed,
                    noise=not args.no_noise,
                    progress=LiveStatus(live),
                    report=not args.no_report,
                    strategy=strategy,
                    overwrite=args.overwrite,
                    live=server,
                )
    except KeyboardInterrupt as exc:
        log = out / "log.mcap"
        kept = f"the log of the run so far is {log}" if log.exists() else "nothing was written"
        console.print(f"interrupted ({interruption_reason(exc)}): {kept}; no results were computed")
        return EXIT_INTERRUPTED
    finally:
        if server is not None:
            live_server.stop_live(server, console)
    print_results(results, console)
    if args.video is not None and not _write_video(args, sc, out / "log.mcap", console):
        return 1
    if not args.no_report:
        console.print(f"report: {out / 'report.md'}")
    from twin.run.campaign_run import dropped_visits

    dropped = dropped_visits(results, sc)
    print_dropped(dropped, len(sc.calibration.visits), console)
    return 1 if dropped or not results["calibrations"] else 0


def print_dropped(dropped: list[dict], visits: int, console: Console) -> None:
    """The visits a run dropped (:func:`twin.run.campaign_run.dropped_visits`), one a line:
    camera, visit number and the recorded reason."""
    if not dropped:
        return
    console.print(f"[red]dropped {len(dropped)} of the scenario's {visits} visits:[/red]")
    for d in dropped:
        why = f"{d['reason']}: {d['message']}" if d["message"] else d["reason"]
        console.print(f"  {d['camera']} visit {d['visit']}: {escape(why)}")


def _write_video(args: argparse.Namespace, sc: object, log: Path, console: Console) -> bool:
    """``--video``: the run's video, rendered from its log with a progress bar; False (and
    why said) when it cannot be rendered or written (the run's outputs stay)."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeRemainingColumn

    from calib.io.atomic import atomic_file
    from twin.run.video import render_video

    if args.seed is not None:
        sc = sc.model_copy(update={"seed": args.seed})  # type: ignore[attr-defined]
    from twin.sim.gl import RenderBackendError

    columns = ("rendering the video", BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
    try:
        with (
            Progress(*columns, console=console, transient=True) as bar,
            atomic_file(args.video) as tmp,
        ):
            task = bar.add_task("video", total=None)

            def advance(done: int, frames: int) -> None:
                bar.update(task, completed=done, total=frames)

            frames = render_video(sc, log, tmp, period=args.video_period, progress=advance)  # type: ignore[arg-type]
    except (RenderBackendError, OSError) as exc:
        console.print(f"[red]error:[/red] --video {args.video}: {escape(str(exc))}")
        return False
    console.print(f"video: {args.video} ({frames} frames)")
    return True


def _run_on_rig(
    args: argparse.Namespace,
    sc: object,
    out: Path,
    strategy: Strategy,
    display: LiveStatus,
    console: Console,
    server: LiveServer | None,
) -> dict | None:
    """The campaign on the rig file's devices; None (and the error shown) for a bad rig file
    or a device that cannot be opened."""
    from twin.drivers.build import DeviceConnectError
    from twin.drivers.rig_file import RigFileError
    from twin.run.hardware_run import run_on_rig

    try:
        return run_on_rig(
            sc,  # type: ignore[arg-type]
            args.rig,
            out,
            progress=display,
            report=not args.no_report,
            strategy=strategy,
            overwrite=args.overwrite,
            live=server,
        )
    except RigFileError as exc:
        console.print(str(exc), markup=False)
    except (DeviceConnectError, ImportError) as exc:
        console.print(f"[red]error:[/red] {escape(str(exc))}", highlight=False)
    return None


def print_results(results: dict, console: Console) -> None:
    """The calibrations as a Table III-like table, and the failures."""
    how = f"{results['fidelity']}, {results.get('strategy') or 'paper'} strategy"
    # Short headings and the units in the caption: the table fits 80 columns (a log, CI).
    table = Table(
        title=f"{results['scenario']} ({how}, seed {results['seed']})",
        caption="travel in m; 3D errors and the true position error in mm",
        box=box.SIMPLE_HEAVY,
    )
    for col in ("camera", "visit", "travel", "points", "world px", "world 3D", "local px"):
        table.add_column(col, justify="right")
    for col in ("local 3D", "true err"):
        table.add_column(col, justify="right")
    for c in results["calibrations"]:
        w, loc, truth = c["errors"]["world"], c["errors"]["local"], c["truth"]
        table.add_row(
            c["camera"],
            str(c["visit"]),
            f"{c['distance_travelled_m']:.1f}",
            str(c["points"]),
            "-" if w is None else f"{w['pixel_mean']:.2f}",
            "-" if w is None else f"{w['error_3d_mean_mm']:.2f}",
            "-" if loc is None else f"{loc['pixel_mean']:.2f}",
            "-" if loc is None else f"{loc['error_3d_mean_mm']:.2f}",
            "-" if truth is None else f"{truth['position_error_mm']:.1f}",
        )
    console.print(table)
    print_adjustment(results, console)
    if results.get("aborted"):
        console.print(f"[red]campaign aborted:[/red] {escape(results['aborted'])}")
    for s in results["skipped_visits"]:
        line = f"skipped {s['camera']} visit {s['visit']}: {s['reason']} ({s['message']})"
        console.print(line, markup=False)
    if results["failures"]:
        console.print("failures: " + ", ".join(f"{k} {v}" for k, v in results["failures"].items()))
    if results.get("events"):
        console.print("events: " + ", ".join(f"{k} {v}" for k, v in results["events"].items()))
    if results["parent_final_error_mm"] is not None:
        wall = results["wall_time_s"]
        console.print(
            f"parent travelled {results['distance_travelled_m']:.1f} m; final position error "
            f"{results['parent_final_error_mm']:.1f} mm"
            + ("" if wall is None else f"; wall time {wall:.1f} s")
        )


def print_adjustment(results: dict, console: Console) -> None:
    """The adjusted calibrations beside the sequential ones, or why there are none."""
    info = results.get("adjustment")
    if not info:
        return
    if info["status"] != "adjusted":
        console.print(f"global adjustment: {info['message']}")
        return
    table = Table(
        title=f"global adjustment ({info['cameras']} cameras; chi2/dof "
        f"{info['variance_factor']:.2f}; measured twice: {'; '.join(info['redundancy'])})",
        caption="errors in mm",
        box=box.SIMPLE_HEAVY,
    )
    for col in ("camera", "visit", "world 3D", "adjusted", "true err", "adjusted"):
        table.add_column(col, justify="right")
    for c, a in zip(results["calibrations"], results["adjusted_calibrations"], strict=False):
        cells = []
        for entry in (c, a):
            w = entry["errors"]["world"]
            cells.append("-" if w is None else f"{w['error_3d_mean_mm']:.2f}")
        for entry in (c, a):
            truth = entry["truth"]
            cells.append("-" if truth is None else f"{truth['position_error_mm']:.1f}")
        table.add_row(c["camera"], str(c["visit"]), cells[0], cells[1], cells[2], cells[3])
    console.print(table)
    if info.get("consistent") is False:
        console.print(f"[yellow]warning:[/yellow] global adjustment: {escape(info['message'])}")
