"""The batch fidelity against the geometric one on the smoke room, to 20 %: the RMS camera
position error of many trials of each, with the paper's stops and the whole campaign (the
reference set included).

Run: ``.venv/bin/python benchmarks/bench_smoke_agreement.py [--geometric 280]
[--batch 3000] [--seed 2026] [--workers 2]``

The errors have about one degree of freedom a trial (one direction dominates: the squared
error's spread is that of a chi-square with one), so the RMS of N trials is known within
about 0.70 / sqrt(N): 280 geometric trials beside 3000 batch trials know the ratio within
about 4.3 % (bootstrap), and the band 1 +- 0.2 is four and a half of those. About 150 s on
one core. The test suite holds the same comparison without the reference set and with
fewer trials, in a wider band (``tests/twin/batch/test_agreement.py``).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from rich.console import Console
from rich.table import Table

from twin.montecarlo import run_montecarlo
from twin.montecarlo.compare import errors_by_trial, rms_ratio
from twin.scenario import load_scenario
from twin.scenario.overrides import with_values

ROOT = Path(__file__).resolve().parents[1]
SMOKE = ROOT / "scenarios" / "smoke.toml"
BAND = 0.2
"""The agreement asked for: RMS errors within this fraction of each other."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--geometric", type=int, default=280, help="geometric trials")
    parser.add_argument("--batch", type=int, default=3000, help="batch trials")
    parser.add_argument("--seed", type=int, default=2026, help="master seed of both runs")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    console = Console()
    smoke = with_values(load_scenario(SMOKE), {"campaign.strategy": "paper"})
    walls = {}
    with tempfile.TemporaryDirectory() as tmp:
        runs = {}
        for fidelity, trials in (("geometric", args.geometric), ("batch", args.batch)):
            t0 = time.perf_counter()
            runs[fidelity] = run_montecarlo(
                smoke,
                Path(tmp) / fidelity,
                trials,
                fidelity=fidelity,
                master_seed=args.seed,
                workers=args.workers,
            )
            walls[fidelity] = time.perf_counter() - t0
    r = rms_ratio(errors_by_trial(runs["geometric"]), errors_by_trial(runs["batch"]))
    table = Table(title="RMS camera position error, smoke room, paper's stops")
    for col in ("fidelity", "trials", "RMS, mm", "wall s"):
        table.add_column(col, justify="right")
    table.add_row("geometric", str(r.trials_a), f"{r.rms_a:.2f}", f"{walls['geometric']:.0f}")
    table.add_row("batch", str(r.trials_b), f"{r.rms_b:.2f}", f"{walls['batch']:.0f}")
    console.print(table)
    ratio = Table(title="batch / geometric")
    for col in ("ratio", "bootstrap std", "95 % interval", "band", "band / std", "verdict"):
        ratio.add_column(col, justify="right")
    inside = abs(r.ratio - 1.0) <= BAND
    ratio.add_row(
        f"{r.ratio:.3f}",
        f"{r.std:.3f}",
        f"{r.low:.3f} .. {r.high:.3f}",
        f"1 +- {BAND}",
        f"{BAND / r.std:.1f}",
        "agree" if inside and 4 * r.std <= BAND else "not shown to agree",
    )
    console.print(ratio)


if __name__ == "__main__":
    main()
