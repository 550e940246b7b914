"""``twin strategies``: route and formation policies compared in the environment."""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import asdict
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from twin.cli import arguments
from twin.cli.scene import load_or_report
from twin.outputs import check_folder, claim_folder

OUTPUTS = ("episodes.csv", "summary.json", "tradeoff.png")
"""What the command writes in its folder."""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``strategies`` subcommand."""
    from twin.envs import POLICY_NAMES

    p = sub.add_parser(
        "strategies",
        help="compare route and formation policies in the Gymnasium environment",
        description=(
            "Play N episodes of each policy in camnet/CpsCampaign-v0 (the campaign, its "
            "moves chosen by the policy, the scenario's noise; episode k of every policy has "
            "the same seed). Prints a table per policy (the cameras' world-frame errors, "
            "travel, time, decisions per second) and writes DIR/episodes.csv, "
            "DIR/summary.json and DIR/tradeoff.png (error against travel, a point per "
            "episode). Exit code 0; 2 for bad input (nothing written)."
        ),
    )
    p.add_argument(
        "scenario",
        help="scenario file (.toml or .yaml), or 'random' for a random site per episode",
    )
    p.add_argument(
        "--policy",
        nargs="+",
        choices=POLICY_NAMES,
        default=list(POLICY_NAMES),
        help="policies to compare (default: all)",
    )
    p.add_argument(
        "--episodes", type=arguments.positive_int, default=20, help="episodes per policy (20)"
    )
    p.add_argument(
        "--seed",
        type=arguments.seed,
        default=0,
        help="episode k's seed is SEED + k, every one from 0 to 2^63 - 1 (default: 0)",
    )
    p.add_argument(
        "--budget",
        type=arguments.positive_float,
        help="the parent's travel allowed per episode, m (default 2.5 route lengths)",
    )
    p.add_argument(
        "--planner",
        choices=("campaign", "stands"),
        default="campaign",
        help=(
            "how the moves are played: 'campaign' (the campaign itself, default) or "
            "'stands' (a table of the site: fast, see docs/environment.md)"
        ),
    )
    p.add_argument(
        "--out", type=Path, help="output folder, empty or new (default: out/SITE-strategies)"
    )
    arguments.add_overwrite(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run; exit code 0, or 2 for bad input."""
    console = Console(highlight=False, soft_wrap=True, width=max(110, Console().width))
    last = args.seed + args.episodes - 1
    if last > arguments.SEED_MAX:
        console.print(
            f"error: --seed {args.seed} with --episodes {args.episodes}: the last episode's "
            f"seed {last} is above 2^63 - 1; expected --seed from 0 to "
            f"{arguments.SEED_MAX - args.episodes + 1}",
            markup=False,
        )
        return 2
    scenario = None
    if args.scenario != "random":
        scenario = load_or_report(Path(args.scenario), console)
        if scenario is None:
            return 2
    from twin.envs.comparison import play_episodes, summarise, tradeoff_figure, write_episodes

    site = "random" if scenario is None else scenario.name
    out = args.out or Path("out") / f"{site}-strategies"
    check_folder(out, "strategies", OUTPUTS, overwrite=args.overwrite)
    policies = list(dict.fromkeys(args.policy))
    console.print(
        f"{args.episodes} episodes x {len(policies)} policies on [bold]{site}[/bold], into {out}"
    )
    columns = (
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
    )
    with Progress(*columns, console=console) as bar:
        tasks = {name: bar.add_task(name, total=args.episodes) for name in policies}
        try:
            episodes = play_episodes(
                scenario,
                policies,
                args.episodes,
                args.seed,
                progress=lambda name, done: bar.update(tasks[name], completed=done),
                budget_m=args.budget,
                planner=args.planner,
            )
        except (ValueError, RuntimeError) as exc:
            console.print(f"[red]error:[/red] {exc}", markup=True)
            return 2
    summaries = summarise(episodes)
    table = Table(title=f"{site}: {args.episodes} episodes per policy")
    for name in (
        "policy",
        "camera median mm",
        "camera p90 mm",
        "calibrated",
        "travel m",
        "time h",
        "parent median mm",
        "steps/s",
    ):
        table.add_column(name, justify="left" if name == "policy" else "right")
    for s in summaries:
        table.add_row(
            s.policy,
            _number(s.camera_median_mm, 1),
            _number(s.camera_p90_mm, 1),
            f"{100 * s.calibrated:.0f} %",
            f"{s.distance_m:.1f}",
            f"{s.time_s / 3600:.2f}",
            _number(s.parent_median_mm, 1),
            f"{s.steps_per_s:.0f}",
        )
    console.print(table)
    folder = claim_folder(
        out, "strategies", OUTPUTS, arguments.recorded(args), overwrite=args.overwrite
    )
    write_episodes(episodes, out / "episodes.csv")
    (out / "summary.json").write_text(
        json.dumps([asdict(s) for s in summaries], indent=2, allow_nan=True) + "\n"
    )
    tradeoff_figure(episodes, out / "tradeoff.png", f"{site}: camera error against travel")
    folder.finished(episodes=len(episodes))
    console.print(f"episodes: {out / 'episodes.csv'}\nfigure: {out / 'tradeoff.png'}")
    return 0


def _number(value: float, digits: int) -> str:
    return "-" if math.isnan(value) else f"{value:.{digits}f}"
