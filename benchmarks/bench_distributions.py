"""Whether a change of the code keeps the distribution of the camera errors: a Monte Carlo
of the hall before and after, at one fidelity, and per planned visit the RMS camera
position error of each, their ratio and its 95 % bootstrap interval, paired by trial seed
(both runs share the master seed, so trial i sees the same noise in both).

    .venv/bin/python benchmarks/bench_distributions.py BEFORE AFTER [--fidelity batch]

BEFORE and AFTER are each a git revision (exported with ``git archive`` into a temporary
folder), a source tree (a folder with ``twin/``), or the ``trials.csv`` of a Monte Carlo
run already made (the runs take a while at the geometric fidelity: start them early with
``--keep DIR`` and read them again). The default trials are 1000 at the batch fidelity and
200 at the geometric one; the scenario is the paper's hall, the strategy the paper's, with
``--no-budget``. A visit passes when its interval holds 1; the exit code is 1 when one
does not.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

from rich.console import Console
from rich.table import Table

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from twin.montecarlo.compare import errors_by_visit, visit_rms_ratio  # noqa: E402
from twin.montecarlo.table import read_table  # noqa: E402

TRIALS = {"batch": 1000, "geometric": 200, "render": 20}
"""Trials of each fidelity, unless --trials says otherwise."""


def _tree(source: str, tmp: Path) -> Path:
    """The source tree of ``source``: a folder as it is, or a revision exported."""
    path = Path(source)
    if path.is_dir() and (path / "twin").is_dir():
        return path.resolve()
    rev = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--verify", f"{source}^{{commit}}"],
        capture_output=True,
        text=True,
    )
    if rev.returncode != 0:
        raise SystemExit(f"{source}: neither a source tree, a trials.csv nor a git revision")
    tree = tmp / rev.stdout.strip()[:12]
    tree.mkdir(parents=True, exist_ok=True)
    archive = subprocess.run(
        ["git", "-C", str(ROOT), "archive", rev.stdout.strip()], capture_output=True, check=True
    )
    subprocess.run(["tar", "-x", "-C", str(tree)], input=archive.stdout, check=True)
    return tree


def _table(source: str, args: argparse.Namespace, tmp: Path, label: str) -> Path:
    """The trials.csv of ``source``: given, or made by a Monte Carlo in its tree."""
    if source.endswith(".csv"):
        return Path(source)
    tree = _tree(source, tmp)
    out = (args.keep / label) if args.keep else tmp / f"mc-{label}"
    command = [
        sys.executable,
        "-m",
        "twin.cli",
        "montecarlo",
        str(tree / args.scenario),
        "--trials",
        str(args.trials),
        "--fidelity",
        args.fidelity,
        "--strategy",
        args.strategy,
        "--workers",
        str(args.workers),
        "--no-budget",
        "--out",
        str(out),
        "--overwrite",
        *(("--seed", str(args.seed)) if args.seed is not None else ()),
    ]
    print(f"{label}: {source} in {tree}", flush=True)
    subprocess.run(command, cwd=tree, check=True)
    return out / "trials.csv"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("before", help="git revision, source tree or trials.csv")
    parser.add_argument("after", help="git revision, source tree or trials.csv")
    parser.add_argument("--fidelity", choices=tuple(TRIALS), default="batch")
    parser.add_argument("--trials", type=int, help="default: 1000 batch, 200 geometric")
    parser.add_argument("--scenario", default="scenarios/paper_hall.toml")
    parser.add_argument("--strategy", default="paper")
    parser.add_argument("--seed", type=int, help="master seed of both (the scenario's)")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--column", default="position_error_mm", help="the error compared")
    parser.add_argument("--resamples", type=int, default=9999)
    parser.add_argument("--keep", type=Path, help="keep the runs in DIR/before, DIR/after")
    args = parser.parse_args(argv)
    args.trials = args.trials or TRIALS[args.fidelity]
    with tempfile.TemporaryDirectory() as tmp:
        tables = [
            read_table(_table(source, args, Path(tmp), label))
            for source, label in ((args.before, "before"), (args.after, "after"))
        ]
    before, after = (errors_by_visit(rows, args.column) for rows in tables)
    table = Table(title=f"RMS {args.column}, {args.fidelity}: after / before, 95 % bootstrap")
    for name in ("camera", "visit", "trials", "RMS before", "RMS after", "ratio", "95 %", ""):
        table.add_column(name, justify="left" if name in ("camera", "") else "right")
    failed = 0
    for key in [*before, *(k for k in after if k not in before)]:  # campaign order
        old, new = before.get(key, {}), after.get(key, {})
        try:
            r = visit_rms_ratio(old, new, args.resamples)
        except ValueError as exc:
            failed += 1
            table.add_row(key[0], str(key[1]), f"{len(old)}/{len(new)}", "", "", "", "", str(exc))
            continue
        failed += not r.agrees
        table.add_row(
            key[0],
            str(key[1]),
            f"{r.trials_before}" + ("" if r.paired else f"/{r.trials_after}"),
            f"{r.rms_before:.3f}",
            f"{r.rms_after:.3f}",
            f"{r.ratio:.4f}",
            f"{r.low:.4f}-{r.high:.4f}",
            "pass" if r.agrees else "FAIL: the interval does not hold 1",
        )
    Console(width=120).print(table)
    print("trials: paired by seed (one count) or apart (before/after)")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
