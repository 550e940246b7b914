"""Wall time of the paper's campaign at each fidelity, and where the time goes.

Runs ``twin run scenarios/paper_hall.toml`` (the runner, without the report) at the
geometric and the render fidelity for a few seeds, and prints per run: calibrations made,
wall time and its split (physics, rendering, LED detection, planning, solving, other),
the ratio render / geometric measured in this run, and the Table III numbers beside the
paper's.

    .venv/bin/python benchmarks/bench_campaign.py [--seeds 1 2 3]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

import twin.sim  # noqa: F401  # isort: skip
from twin.report.paper import table_iii
from twin.run.runner import run_scenario

HALL = Path(__file__).resolve().parents[1] / "scenarios" / "paper_hall.toml"
PARTS = ("physics", "render", "detection", "planning", "solving", "other")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[20080922])
    args = parser.parse_args()
    console = Console()
    times = Table(title="twin run scenarios/paper_hall.toml: wall time and where it goes [s]")
    for col in ("fidelity", "seed", "calibrated", "travel [m]", "wall", *PARTS):
        times.add_column(col, justify="right")
    errors = Table(title="Table III: paper | twin (world = vs the reference sets)")
    for col in ("fidelity", "seed", "visit", "world px", "world 3D mm", "local px", "local 3D mm"):
        errors.add_column(col, justify="right")
    errors.add_column("position err [mm]", justify="right")
    walls: dict[str, list[float]] = {"geometric": [], "render": []}
    pos: dict[str, list[float]] = {"geometric": [], "render": []}
    for fidelity in ("geometric", "render"):
        for seed in args.seeds:
            with tempfile.TemporaryDirectory() as tmp:
                res = run_scenario(
                    HALL, tmp, fidelity=fidelity, seed=seed, report=False, strategy="paper"
                )
            t = res["timings_s"]
            walls[fidelity].append(res["wall_time_s"])
            times.add_row(
                fidelity,
                str(seed),
                f"{len(res['calibrations'])}/5",
                f"{res['distance_travelled_m']:.1f}",
                f"{res['wall_time_s']:.1f}",
                *(f"{t.get(p, 0.0):.1f}" for p in PARTS),
            )
            for c in res["calibrations"]:
                pos[fidelity].append(c["truth"]["position_error_mm"])
                w, loc = c["errors"]["world"], c["errors"]["local"]
                paper = table_iii(c["camera"], c["visit"])

                def pair(ours: float | None, theirs: float | None) -> str:
                    a = "-" if theirs is None else f"{theirs:.2f}"
                    b = "-" if ours is None else f"{ours:.2f}"
                    return f"{a} | {b}"

                errors.add_row(
                    fidelity,
                    str(seed),
                    f"{c['camera']} #{c['visit']} ({c['distance_travelled_m']:.0f} m)",
                    pair(w and w["pixel_mean"], paper and paper.world_pixel),
                    pair(w and w["error_3d_mean_mm"], paper and paper.world_3d_mm),
                    pair(loc["pixel_mean"], paper and paper.local_pixel),
                    pair(loc["error_3d_mean_mm"], paper and paper.local_3d_mm),
                    f"{c['truth']['position_error_mm']:.1f}",
                )
    console.print(times)
    ratio = np.median(walls["render"]) / np.median(walls["geometric"])
    console.print(f"render / geometric wall time (median over seeds): {ratio:.1f}x")
    if pos["geometric"] and pos["render"]:
        g, r = np.median(pos["geometric"]), np.median(pos["render"])
        console.print(
            f"median camera position error: geometric {g:.1f} mm, render {r:.1f} mm "
            f"(ratio {max(g, r) / min(g, r):.2f})"
        )
    console.print(errors)


if __name__ == "__main__":
    main()
