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

OUTPUTS = ("episodes.csv", "summary.json", "tradeoff.png", "differences.csv")
"""What the command writes in its folder (``differences.csv`` with ``--baseline``)."""

DEFAULT_EPISODES = 20
"""Episodes per policy on a scenario (a test set plays all of its own)."""

METRIC_UNITS = {
    "true_error_mm": "mm",
    "mean_camera_error_mm": "mm",
    "reward": "",
    "distance_m": "m",
    "time_s": "s",
}
"""The paired differences printed, with their units."""


def _policy(text: str) -> str:
    """A policy's name or a saved model's path (``.zip``; read when the command runs)."""
    from twin.envs import POLICY_NAMES
    from twin.envs.policies import is_model

    if text in POLICY_NAMES or is_model(text):
        return text
    raise argparse.ArgumentTypeError(
        f"invalid choice: {text!r} (choose from {', '.join(POLICY_NAMES)}, or a saved "
        "MaskablePPO model's path ending in .zip)"
    )


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``strategies`` subcommand."""
    from twin.envs import POLICY_NAMES
    from twin.envs.heldout import DEFAULT_TEST_SET, TEST_SETS

    p = sub.add_parser(
        "strategies",
        help="compare route and formation policies in the Gymnasium environment",
        description=(
            "Play N episodes of each policy in camnet/CpsCampaign-v0 (the campaign, its "
            "moves chosen by the policy, the scenario's noise; episode k of every policy has "
            "the same seed). Prints a table per policy (the cameras' world-frame errors, "
            "travel, time, decisions per second) and writes DIR/episodes.csv, "
            "DIR/summary.json and DIR/tradeoff.png (error against travel, a point per "
            "episode). With --test-set the episodes are a held-out test set's (sites and "
            "seeds training never uses, twin.envs.heldout); with --baseline, each policy's "
            "paired differences from the baseline with their 95 % confidence intervals "
            "(printed, and DIR/differences.csv). Exit code 0; 2 for bad input (nothing "
            "written)."
        ),
    )
    p.add_argument(
        "scenario",
        nargs="?",
        help=(
            "scenario file (.toml or .yaml), or 'random' for a random site per episode "
            "(left out with --test-set)"
        ),
    )
    p.add_argument(
        "--policy",
        nargs="+",
        type=_policy,
        default=list(POLICY_NAMES),
        help=(
            f"policies to compare: {', '.join(POLICY_NAMES)}, or a saved MaskablePPO model "
            "(a path ending in .zip; needs sb3-contrib) (default: all the named ones)"
        ),
    )
    p.add_argument(
        "--test-set",
        choices=tuple(TEST_SETS),
        help=(
            "play a held-out test set's episodes instead of a scenario's "
            f"({'; '.join(f'{t.name}: {t.description}' for t in TEST_SETS.values())}; "
            f"a learned policy is judged on {DEFAULT_TEST_SET!r})"
        ),
    )
    p.add_argument(
        "--baseline",
        type=_policy,
        help=(
            "a policy to compare the others with, episode by episode (played too if "
            "--policy leaves it out): paired differences with 95 %% confidence intervals"
        ),
    )
    p.add_argument(
        "--episodes",
        type=arguments.positive_int,
        help=f"episodes per policy ({DEFAULT_EPISODES}; with --test-set: its first N, default all)",
    )
    p.add_argument(
        "--seed",
        type=arguments.seed,
        help=(
            "episode k's seed is SEED + k, every one from 0 to 2^63 - 1 (default: 0; "
            "a test set has its own)"
        ),
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


def _episodes(args: argparse.Namespace, console: Console) -> bool:
    """Fill in the scenario, the episodes and the seed from the scenario or the test set;
    False (the reason printed) where they contradict each other."""
    from twin.envs.heldout import test_set

    def refuse(message: str) -> bool:
        console.print(f"error: {message}", markup=False)
        return False

    if args.test_set is None:
        if args.scenario is None:
            return refuse("expected a scenario file, 'random', or --test-set NAME")
        args.episodes = args.episodes or DEFAULT_EPISODES
        args.seed = args.seed or 0
        return True
    chosen = test_set(args.test_set)
    if args.scenario is not None:
        return refuse(
            f"scenario {args.scenario} with --test-set {chosen.name}: the test set has its own "
            f"site ({chosen.scenario}); give one or the other"
        )
    if args.seed is not None:
        return refuse(f"--seed with --test-set {chosen.name}: the test set has its own seeds")
    if args.episodes is not None and args.episodes > chosen.episodes:
        return refuse(
            f"--episodes {args.episodes} with --test-set {chosen.name}: the test set has "
            f"{chosen.episodes} episodes; expected at most {chosen.episodes}"
        )
    args.episodes = args.episodes or chosen.episodes
    args.seed = chosen.seeds.start
    return True


def run(args: argparse.Namespace) -> int:
    """Run; exit code 0, or 2 for bad input."""
    console = Console(highlight=False, soft_wrap=True, width=max(110, Console().width))
    if not _episodes(args, console):
        return 2
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
    if args.test_set is not None:
        from twin.envs.heldout import test_set

        scenario = test_set(args.test_set).load()
    elif args.scenario != "random":
        scenario = load_or_report(Path(args.scenario), console)
        if scenario is None:
            return 2
    from twin.envs.comparison import (
        paired_differences,
        play_episodes,
        summarise,
        tradeoff_figure,
        write_differences,
        write_episodes,
    )
    from twin.envs.policies import policy_for

    site = "random" if scenario is None else scenario.name
    if args.test_set is not None:
        site = f"test set {args.test_set} ({site})"
    default_out = f"{args.test_set}-test" if args.test_set is not None else site
    out = args.out or Path("out") / f"{default_out}-strategies"
    check_folder(out, "strategies", OUTPUTS, overwrite=args.overwrite)
    policies = list(dict.fromkeys(args.policy))
    if args.baseline is not None and args.baseline not in policies:
        policies.insert(0, args.baseline)
    try:
        resolved = {name: policy_for(name) for name in policies}  # a model is loaded once
    except ValueError as exc:
        console.print(f"error: {exc}", markup=False)
        return 2
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
                resolved,
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
    differences = []
    if args.baseline is not None:
        differences = paired_differences(episodes, args.baseline, tuple(METRIC_UNITS))
        console.print(_differences_table(differences, args.baseline))
    folder = claim_folder(
        out, "strategies", OUTPUTS, arguments.recorded(args), overwrite=args.overwrite
    )
    write_episodes(episodes, out / "episodes.csv")
    (out / "summary.json").write_text(
        json.dumps([asdict(s) for s in summaries], indent=2, allow_nan=True) + "\n"
    )
    tradeoff_figure(episodes, out / "tradeoff.png", f"{site}: camera error against travel")
    if differences:
        write_differences(differences, out / "differences.csv")
    folder.finished(episodes=len(episodes))
    console.print(f"episodes: {out / 'episodes.csv'}\nfigure: {out / 'tradeoff.png'}")
    if differences:
        console.print(f"paired differences: {out / 'differences.csv'}")
    return 0


def _differences_table(differences: list, baseline: str) -> Table:
    """Each policy's paired differences from the baseline (:class:`PairedDifference`)."""
    table = Table(title=f"paired by seed: policy - {baseline}, mean and 95 % interval")
    names = ("policy", "metric", "pairs", "policy mean", f"{baseline} mean", "difference", "95 %")
    for name in names:
        table.add_column(name, justify="left" if name in ("policy", "metric") else "right")
    for d in differences:
        unit = METRIC_UNITS.get(d.metric, "")
        table.add_row(
            d.policy,
            f"{d.metric}" + (f" [{unit}]" if unit else ""),
            str(d.pairs),
            _number(d.policy_mean, 1),
            _number(d.baseline_mean, 1),
            _number(d.mean, 2),
            f"{_number(d.low, 2)} .. {_number(d.high, 2)}",
        )
    return table


def _number(value: float, digits: int) -> str:
    return "-" if math.isnan(value) else f"{value:.{digits}f}"
