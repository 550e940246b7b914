"""Do the two fidelities agree? Camera position errors of the paper's campaign at the
``geometric`` and ``render`` fidelities, over Monte-Carlo trials with the same seeds.

Run: ``.venv/bin/python benchmarks/bench_fidelity.py [--trials N] [--workers K]
[--geometric DIR] [--render DIR]``

Each fidelity runs ``twin montecarlo scenarios/paper_hall.toml --no-budget`` with one
master seed (so trial i has the same seed at both, and the instrument's keyed noise is
shared where the runs measure the same things), into ``out/bench-fidelity/FIDELITY``;
a folder that already holds such a run is resumed, and ``--geometric``/``--render`` read
finished runs instead. The baseline of the ratios is the geometric run of the same
benchmark: render median / geometric median, with a bootstrap interval over trials. The
last table shows how often two batches of a few seeds of *one* fidelity differ by more
than the factor, which is what a comparison over a handful of seeds can decide.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

import twin.sim  # noqa: F401  # isort: skip
from twin.montecarlo import run_montecarlo
from twin.montecarlo.compare import batch_disagreement, errors_by_trial, median_ratio
from twin.montecarlo.run import SETTINGS, TABLE
from twin.montecarlo.summary import visit_summary
from twin.montecarlo.table import read_table
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
HALL = ROOT / "scenarios" / "paper_hall.toml"
FACTOR = 1.5
"""The agreement asked for: medians within this factor."""


def _table(fidelity: str, folder: Path | None, trials: int, workers: int, seed: int) -> tuple:
    if folder is None:
        folder = ROOT / "out" / "bench-fidelity" / fidelity
        resume = (folder / SETTINGS).exists()
        run_montecarlo(
            load_scenario(HALL),
            folder,
            trials,
            fidelity=fidelity,
            master_seed=seed,
            workers=workers,
            resume=resume,
            strategy="paper",
        )
    settings = json.loads((folder / SETTINGS).read_text())
    return read_table(folder / TABLE), settings


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=30, help="trials per fidelity")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=100, help="master seed of both runs")
    parser.add_argument("--geometric", type=Path, help="a finished geometric run to read")
    parser.add_argument("--render", type=Path, help="a finished render run to read")
    args = parser.parse_args()
    console = Console()
    geo, geo_settings = _table("geometric", args.geometric, args.trials, args.workers, args.seed)
    ren, ren_settings = _table("render", args.render, args.trials, args.workers, args.seed)
    if geo_settings["master_seed"] != ren_settings["master_seed"]:
        console.print("note: the two runs have different master seeds (no shared noise)")

    visits = Table(title="Camera position error per visit, mm: median (p90)")
    for col in ("visit", "travel, m", "geometric", "render", "render / geometric"):
        visits.add_column(col, justify="right")
    for g, r in zip(visit_summary(geo), visit_summary(ren), strict=True):
        gm, rm = g["position_error_mm"], r["position_error_mm"]
        visits.add_row(
            f"{g['camera']} #{g['visit']}",
            f"{g['distance_travelled_m']['median']:.0f}",
            f"{gm['median']:.1f} ({gm['p90']:.1f})",
            f"{rm['median']:.1f} ({rm['p90']:.1f})",
            f"{rm['median'] / gm['median']:.2f}",
        )
    console.print(visits)

    a, b = errors_by_trial(geo), errors_by_trial(ren)
    ratio = median_ratio(a, b)
    pooled = Table(title="Pooled over visits (baseline: the geometric run)")
    for col in ("trials", "geometric median", "render median", "ratio", "95 % interval"):
        pooled.add_column(col, justify="right")
    pooled.add_row(
        f"{ratio.trials_a} / {ratio.trials_b}",
        f"{ratio.median_a:.1f}",
        f"{ratio.median_b:.1f}",
        f"{ratio.ratio:.2f}",
        f"{ratio.low:.2f} .. {ratio.high:.2f}",
    )
    console.print(pooled)
    inside = ratio.low >= 1.0 / FACTOR and ratio.high <= FACTOR
    verdict = "agree" if inside else "are not shown to agree"
    console.print(
        f"the fidelities {verdict} within a factor {FACTOR} (the whole interval inside "
        f"{1 / FACTOR:.2f} .. {FACTOR})"
    )

    few = Table(title=f"Two batches of k seeds of one fidelity: how often > x{FACTOR} apart")
    for col in ("k", "geometric", "render", "95 % range of the ratio (geometric)"):
        few.add_column(col, justify="right")
    for k in (3, 5, 10):
        if 2 * k > min(len(a), len(b)):
            continue
        pg, (lo, hi) = batch_disagreement(a, k, FACTOR)
        pr, _ = batch_disagreement(b, k, FACTOR)
        few.add_row(str(k), f"{pg:.0%}", f"{pr:.0%}", f"{lo:.2f} .. {hi:.2f}")
    console.print(few)
    rates = [s.get("trials_per_second") for s in (geo_settings, ren_settings)]
    if all(r is not None and np.isfinite(r) and r > 0 for r in rates):
        console.print(
            f"wall time per trial: render / geometric = {rates[0] / rates[1]:.1f} "
            "(the last session of each run)"
        )


if __name__ == "__main__":
    main()
