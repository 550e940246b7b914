"""``twin montecarlo``: Monte-Carlo error budgets of a scenario's campaign."""

from __future__ import annotations

import argparse
from pathlib import Path

from rich.console import Console
from rich.markup import escape
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from twin.cli import arguments
from twin.cli.scene import load_or_report
from twin.interruption import EXIT_INTERRUPTED, interruption_reason
from twin.outputs import check_folder

MAX_WORKERS = 4096
"""The most ``--workers``: more processes than a machine runs, or CPUs than a Ray cluster
lends one run (a process pool's count must also fit a C int)."""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``montecarlo`` subcommand."""
    p = sub.add_parser(
        "montecarlo",
        help="Monte-Carlo error budget of a scenario's campaign",
        description=(
            "Run N independent trials of the whole campaign (trial i's seed follows from the "
            "master seed and i alone), with all noise sources and, for the error budget, "
            "with each source alone. Writes DIR/trials.csv (a row per trial and camera "
            "visit, appended as trials finish), DIR/summary.json, DIR/figures/ and "
            "DIR/report.md. Exit code 0; 1 when a trial failed (the finished ones are kept) "
            "or no trial calibrated a camera; "
            "2 for bad input (nothing written); 130 when interrupted (Ctrl-C, SIGTERM: "
            "--resume continues, with the options that define the numbers unchanged and "
            "--trials the same or more)."
        ),
    )
    p.add_argument("scenario", type=Path, help="scenario file (.toml or .yaml)")
    p.add_argument(
        "--trials",
        type=arguments.positive_int,
        required=True,
        help="trials per configuration (required; at most what a table of 2,000,000 rows, "
        "trials x configurations x planned visits, holds; with --resume, as many as the run "
        "has or more: the run goes on to the new count)",
    )
    p.add_argument(
        "--fidelity",
        choices=("batch", "geometric", "render"),
        default="batch",
        help="batch (default): the campaign's plan for many trials at once, as arrays "
        "(see docs/montecarlo.md for what it leaves out); geometric: each trial a campaign with "
        "robots placed with a stopping error, LEDs projected; render: robots driven in "
        "MuJoCo, rendered images",
    )
    p.add_argument(
        "--adjust",
        action="store_true",
        help="at the batch fidelity, also adjust each trial's whole campaign at once (the "
        "adjusted_* columns; 13 trials/s instead of 100 on the paper's hall); the geometric and "
        "render fidelities always do",
    )
    p.add_argument(
        "--chunk-size",
        type=arguments.positive_int,
        help="trials one array holds at the batch fidelity (default: the trials shared "
        "evenly among the workers, at most 200)",
    )
    p.add_argument(
        "--workers",
        type=arguments.int_from_1_to(MAX_WORKERS, "processes or CPUs"),
        default=1,
        help=f"processes (local) or Ray CPUs, 1 to {MAX_WORKERS} (default 1)",
    )
    p.add_argument(
        "--engine",
        choices=("local", "ray"),
        default="local",
        help="local: a process pool on this machine (default); ray: Ray tasks",
    )
    p.add_argument(
        "--ray-address", help="address of an existing Ray cluster (default: start one here)"
    )
    p.add_argument(
        "--seed", type=arguments.seed, help="master seed, 0 to 2^63 - 1 (default: the scenario's)"
    )
    arguments.add_strategy(p)
    p.add_argument(
        "--no-budget",
        action="store_true",
        help="only trials with every noise source (no one-source runs, no budget; default: "
        "the budget too)",
    )
    p.add_argument(
        "--out", type=Path, help="output folder, empty or new (default: out/SCENARIO-montecarlo)"
    )
    again = p.add_mutually_exclusive_group()
    again.add_argument(
        "--resume",
        action="store_true",
        help="continue the Monte-Carlo run in --out (default: start one)",
    )
    arguments.add_overwrite(again)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run; exit code 0, 1 when a trial failed or none calibrated a camera, 2 for bad
    input, 130 when interrupted."""
    console = Console(highlight=False, soft_wrap=True)
    sc = load_or_report(args.scenario, console)
    if sc is None:
        return 2
    from twin.montecarlo import run_montecarlo
    from twin.montecarlo.run import OUTPUTS, check_trials
    from twin.montecarlo.sources import configurations
    from twin.montecarlo.summary import failure_summary
    from twin.montecarlo.trial import TrialFailed

    if args.ray_address and args.engine != "ray":
        console.print("[red]error:[/red] --ray-address goes with --engine ray")
        return 2
    if args.chunk_size is not None and args.fidelity != "batch":
        console.print("[red]error:[/red] --chunk-size goes with --fidelity batch")
        return 2
    out = args.out or Path("out") / f"{sc.name}-montecarlo"
    configs = configurations(not args.no_budget)
    try:
        check_trials(sc, args.trials, configs)
    except ValueError as exc:
        console.print(f"[red]error:[/red] {escape(str(exc))}")
        return 2
    check_folder(out, "montecarlo", OUTPUTS, overwrite=args.overwrite, resume=args.resume)
    console.print(
        f"{args.trials} trials x {len(configs)} configurations of [bold]{sc.name}[/bold] at "
        f"the {args.fidelity} fidelity, {args.workers} worker(s), engine {args.engine}, "
        f"into {out}"
    )
    columns = (
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[rate]}"),
        TimeElapsedColumn(),
        TextColumn("left"),
        TimeRemainingColumn(),
    )
    with Progress(*columns, console=console) as bar:
        task = bar.add_task("trials", total=None, rate="")

        def show(p: object) -> None:
            bar.update(
                task,
                completed=p.done,  # type: ignore[attr-defined]
                total=p.total,  # type: ignore[attr-defined]
                rate=f"{p.rate:.2f}/s",  # type: ignore[attr-defined]
            )

        try:
            rows = run_montecarlo(
                sc,
                out,
                args.trials,
                fidelity=args.fidelity,
                master_seed=args.seed,
                budget=not args.no_budget,
                workers=args.workers,
                engine=args.engine,
                ray_address=args.ray_address,
                resume=args.resume,
                progress=show,
                strategy=args.strategy,
                overwrite=args.overwrite,
                chunk_size=args.chunk_size,
                adjust=args.adjust,
            )
        except TrialFailed as exc:
            console.print(f"[red]error:[/red] {escape(str(exc))}", highlight=False)
            console.print(f"the finished trials are in {out}; --resume continues the run")
            return 1
        except (ValueError, FileNotFoundError, RuntimeError) as exc:
            console.print(f"[red]error:[/red] {escape(str(exc))}")
            return 2
        except KeyboardInterrupt as exc:
            console.print(
                f"interrupted ({interruption_reason(exc)}): the finished trials are in {out}; "
                "--resume continues"
            )
            return EXIT_INTERRUPTED
    console.print(f"table: {out / 'trials.csv'}\nreport: {out / 'report.md'}")
    if not any(r["calibrated"] for r in rows):
        reasons = failure_summary(rows)["not_calibrated"]
        why = ", ".join(f"{reason} {n}" for reason, n in reasons.items())
        console.print(
            f"[red]no trial calibrated any camera[/red] ({escape(why)}): see the report's failures"
        )
        return 1
    return 0
