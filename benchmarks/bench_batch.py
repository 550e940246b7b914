"""The batch fidelity: throughput against the geometric fidelity, agreement with it and
with the analytic prediction, how the cost grows with the network, memory, a whole budget.

Run: ``.venv/bin/python benchmarks/bench_batch.py [--only SECTION,...]``

Sections (all by default; the agreement section alone takes about ten minutes):

- ``throughput``: trials/s of ``scenarios/paper_hall.toml`` at the batch fidelity with 1
  and 2 workers, against the geometric fidelity measured in the same run (the ratio), and
  the absolute figure per core with the machine's load average.
- ``agreement``: the hall and the corridor, 300 trials at each fidelity: per visit the RMS
  camera position error batch / geometric with a bootstrap 95 % interval, the same for
  the parent's final error, then the analytic prediction / batch Monte Carlo per visit.
- ``growth``: time per trial on generated corridors with 5-40 cameras and 100-800 m of
  route (a camera every 20 m), and on 2 cameras with the route alone growing.
- ``memory``: ``twin montecarlo`` of 100,000 hall trials (2 workers, chunks of 200): the
  peak resident memory of its largest process.
- ``budget``: ``twin montecarlo`` of the hall with 1000 trials and every one-source
  configuration (7000 trials), 2 workers: the wall time, report and figures included.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
import tomllib
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.table import Table

from twin.batch.execute import BatchRun
from twin.batch.steps import record_plan
from twin.montecarlo import run_montecarlo
from twin.montecarlo.compare import rms_ratio
from twin.scenario import load_scenario
from twin.scenario.loader import scenario_from_dict

ROOT = Path(__file__).resolve().parents[1]
HALL = ROOT / "scenarios" / "paper_hall.toml"
CORRIDOR = ROOT / "scenarios" / "corridor.toml"
SECTIONS = ("throughput", "agreement", "growth", "memory", "budget")


def load() -> str:
    one, five, fifteen = os.getloadavg()
    return f"{one:.2f} {five:.2f} {fifteen:.2f}"


def _run(scenario, trials: int, fidelity: str, workers: int, seed: int = 1) -> tuple[list, float]:
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        rows = run_montecarlo(
            scenario, tmp, trials, fidelity=fidelity, workers=workers, master_seed=seed
        )
        return rows, time.perf_counter() - t0


# -- throughput ----------------------------------------------------------------------------------
def throughput(console: Console, batch_trials: int, geometric_trials: int) -> None:
    sc = load_scenario(HALL)
    console.print(f"load average before: {load()} ({os.cpu_count()} CPUs)")
    table = Table(title="Throughput, scenarios/paper_hall.toml (whole runs, plan included)")
    for col in ("workers", "fidelity", "trials", "wall s", "trials/s", "per core", "batch/geom"):
        table.add_column(col, justify="right")
    for workers in (1, 2):
        _, g_wall = _run(sc, geometric_trials * workers, "geometric", workers)
        g_rate = geometric_trials * workers / g_wall
        _, b_wall = _run(sc, batch_trials * workers, "batch", workers)
        b_rate = batch_trials * workers / b_wall
        table.add_row(
            str(workers), "geometric", str(geometric_trials * workers), f"{g_wall:.1f}",
            f"{g_rate:.2f}", f"{g_rate / workers:.2f}", "1",
        )  # fmt: skip
        table.add_row(
            str(workers), "batch", str(batch_trials * workers), f"{b_wall:.1f}",
            f"{b_rate:.1f}", f"{b_rate / workers:.1f}", f"{b_rate / g_rate:.0f}",
        )  # fmt: skip
    console.print(table)
    # Where a batch's time goes: one chunk of 200 in this process, by step kind.
    plan = record_plan(sc, "paper")
    run = BatchRun(plan, list(range(200)))
    spent: dict[str, float] = {}
    t0 = time.perf_counter()
    for step in plan.steps:
        t = time.perf_counter()
        run.step(step)
        kind = type(step).__name__
        spent[kind] = spent.get(kind, 0.0) + time.perf_counter() - t
    total = time.perf_counter() - t0
    split = Table(title=f"One chunk of 200 hall trials, one core: {total:.2f} s")
    split.add_column("step")
    split.add_column("s", justify="right")
    split.add_column("share", justify="right")
    for kind, s in sorted(spent.items(), key=lambda kv: -kv[1]):
        split.add_row(kind, f"{s:.2f}", f"{s / total:.0%}")
    console.print(split)
    console.print(f"load average after: {load()}")


# -- agreement -----------------------------------------------------------------------------------
def _per_visit(rows: Sequence[dict[str, Any]]) -> dict[tuple[str, int], list[np.ndarray]]:
    out: dict[tuple[str, int], list[np.ndarray]] = {}
    for r in rows:
        if r["calibrated"] and np.isfinite(r["position_error_mm"]):
            key = (r["camera"], int(r["visit"]))
            out.setdefault(key, []).append(np.array([r["position_error_mm"]]))
    return out


def _parent(rows: Sequence[dict[str, Any]]) -> list[np.ndarray]:
    final = {}
    for r in rows:
        d = [r["parent_final_dx_mm"], r["parent_final_dy_mm"], r["parent_final_dz_mm"]]
        final[int(r["trial"])] = np.array([np.linalg.norm(d)])
    return [final[t] for t in sorted(final)]


def _prediction_ratio(
    rows: Sequence[dict[str, Any]], key: tuple[str, int], resamples: int = 4000
) -> tuple[float, float, float]:
    """Predicted RMS / Monte-Carlo RMS of one visit, with a paired bootstrap interval."""
    rs = [r for r in rows if (r["camera"], int(r["visit"])) == key and r["calibrated"]]
    e2 = np.array([r["position_error_mm"] ** 2 for r in rs])
    p2 = np.array(
        [r["predicted_transfer_rms_mm"] ** 2 + r["predicted_calibration_rms_mm"] ** 2 for r in rs]
    )
    rng = np.random.default_rng(0)
    pick = rng.integers(0, len(rs), (resamples, len(rs)))
    boot = np.sqrt(p2[pick].mean(axis=1) / e2[pick].mean(axis=1))
    low, high = np.quantile(boot, [0.025, 0.975])
    return float(np.sqrt(p2.mean() / e2.mean())), float(low), float(high)


VERDICTS = ("ratio in 0.85-1.15", "interval holds 1")
"""The ratio's verdicts. With 300 trials the interval alone spans about +-12 %: it cannot lie
inside 0.85-1.15 however well the two agree, so the band is the ratio's, and the interval
says whether the two are told apart."""


def _verdicts(ratio: float, low: float, high: float) -> tuple[str, str]:
    return ("yes" if 0.85 <= ratio <= 1.15 else "NO", "yes" if low <= 1.0 <= high else "NO")


def agreement(console: Console, trials: int) -> None:
    for path in (HALL, CORRIDOR):
        sc = load_scenario(path)
        console.print(f"{path.name}: {trials} trials a fidelity, 2 workers; load {load()}")
        geometric, g_wall = _run(sc, trials, "geometric", 2, seed=5)
        batch, b_wall = _run(sc, trials, "batch", 2, seed=5)
        console.print(f"  geometric {g_wall:.0f} s, batch {b_wall:.1f} s")
        table = Table(title=f"{path.name}: batch / geometric RMS error (bootstrap 95 %)")
        for col in ("visit", "geometric mm", "batch mm", "ratio", "95 % interval", *VERDICTS):
            table.add_column(col, justify="right")
        g_visits, b_visits = _per_visit(geometric), _per_visit(batch)
        rows = [(f"{c} {v}", g_visits[(c, v)], b_visits[(c, v)]) for c, v in sorted(g_visits)]
        rows.append(("parent final", _parent(geometric), _parent(batch)))
        for name, g, b in rows:
            r = rms_ratio(g, b)
            table.add_row(
                name, f"{r.rms_a:.2f}", f"{r.rms_b:.2f}", f"{r.ratio:.3f}",
                f"{r.low:.3f}-{r.high:.3f}", *_verdicts(r.ratio, r.low, r.high),
            )  # fmt: skip
        console.print(table)
        pred = Table(title=f"{path.name}: analytic prediction / batch Monte Carlo per visit")
        for col in ("visit", "ratio", "95 % interval", *VERDICTS):
            pred.add_column(col, justify="right")
        for key in sorted(b_visits):
            ratio, low, high = _prediction_ratio(batch, key)
            pred.add_row(
                f"{key[0]} {key[1]}", f"{ratio:.3f}", f"{low:.3f}-{high:.3f}",
                *_verdicts(ratio, low, high),
            )  # fmt: skip
        console.print(pred)


# -- growth --------------------------------------------------------------------------------------
def corridor(cameras: int, route: float):
    """The corridor of ``scenarios/corridor.toml`` stretched to ``route`` m (no pilasters),
    ``cameras`` cameras spread evenly along it, one visit each."""
    raw = tomllib.loads(CORRIDOR.read_text())
    raw["name"] = f"corridor_{cameras}_cameras_{int(route)}_m"
    raw["space"]["size"] = [route + 6.0, 2.4, 3.0]
    raw["space"].pop("obstacles")
    raw["space"].pop("floor_patches")
    template = raw["cameras"][0]
    raw["cameras"], visits = [], []
    for i in range(cameras):
        x = 5.0 + i * route / cameras
        raw["cameras"].append({**template, "name": f"cam{i + 1}", "position": [x, -0.9, 2.0]})
        visits.append({"camera": f"cam{i + 1}", "station": [x + 1.0, 0.0]})
    raw["calibration"]["visits"] = visits
    raw["route"]["waypoints"] = [[0.0, 0.0], [float(route), 0.0]]
    return scenario_from_dict(raw, file=f"generated {raw['name']}")


def growth(console: Console, trials: int) -> None:
    table = Table(title=f"Cost growth: {trials} trials in one chunk, one core")
    columns = ("cameras", "route m", "plan steps", "plan s", "ms/trial", "us/trial/step")
    for col in (*columns, "calibrated", "parent final mm"):
        table.add_column(col, justify="right")
    cases = [(5, 100), (10, 200), (20, 400), (40, 800), (2, 100), (2, 200), (2, 400), (2, 800)]
    for cameras, route in cases:
        sc = corridor(cameras, route)
        t0 = time.perf_counter()
        plan = record_plan(sc, "paper")
        plan_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        out = BatchRun(plan, list(range(trials))).run()
        per = 1e3 * (time.perf_counter() - t0) / trials
        made = np.mean([v.calibrated.mean() for v in out.calibrations.values()])
        parent = 1e3 * np.sqrt(np.mean(np.sum(out.parent_error**2, axis=1)))
        table.add_row(
            str(cameras), str(route), str(len(plan.steps)), f"{plan_s:.1f}", f"{per:.2f}",
            f"{1e3 * per / len(plan.steps):.1f}", f"{made:.1%}", f"{parent:.0f}",
        )  # fmt: skip
    console.print(table)


# -- memory and a whole budget through the command ---------------------------------------
def _command(console: Console, args: list[str]) -> float:
    """Run ``twin montecarlo`` on the hall with ``args``; its wall time, s."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "twin.cli", "montecarlo", str(HALL), *args]
        cmd += ["--workers", "2", "--out", f"{tmp}/mc"]
        console.print(" ".join(cmd[2:]) + f"   (load {load()})")
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        size = sum(p.stat().st_size for p in Path(tmp, "mc").rglob("*") if p.is_file())
        console.print(f"  outputs {size / 2**20:.0f} MiB; load after {load()}")
    return wall


_MEMORY_CHILD = """
import resource, sys, tempfile, time
from twin.montecarlo import run_montecarlo
from twin.scenario import load_scenario
with tempfile.TemporaryDirectory() as tmp:
    t0 = time.perf_counter()
    run_montecarlo(load_scenario(sys.argv[1]), tmp, int(sys.argv[2]), workers=2, chunk_size=200)
    wall = time.perf_counter() - t0
main = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
workers = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
print(f"{wall} {main} {workers}")
"""


def memory(console: Console, trials: int) -> None:
    console.print(f"memory: {trials} hall trials, 2 workers, chunks of 200 (load {load()})")
    out = subprocess.run(
        [sys.executable, "-c", _MEMORY_CHILD, str(HALL), str(trials)],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.split()
    wall, main, workers = (float(x) for x in out[-3:])
    console.print(
        f"  {wall:.0f} s ({trials / wall:.0f} trials/s); peak RSS: main process {main:.0f} MiB "
        f"(it holds the table's rows), largest worker {workers:.0f} MiB; load after {load()}"
    )


def budget(console: Console, trials: int) -> None:
    wall = _command(console, ["--trials", str(trials)])
    console.print(
        f"budget: {trials} trials x 7 configurations of the hall in {wall:.0f} s "
        f"(target 120 s: {'reached' if wall < 120 else 'not reached'})"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default=",".join(SECTIONS), help="sections, comma-separated")
    parser.add_argument("--agreement-trials", type=int, default=300)
    parser.add_argument("--memory-trials", type=int, default=100_000)
    args = parser.parse_args()
    console = Console(width=130)
    only = args.only.split(",")
    unknown = sorted(set(only) - set(SECTIONS))
    if unknown:
        parser.error(f"unknown sections {unknown}; choose from {', '.join(SECTIONS)}")
    if "throughput" in only:
        throughput(console, batch_trials=1000, geometric_trials=10)
    if "growth" in only:
        growth(console, trials=200)
    if "budget" in only:
        budget(console, 1000)
    if "memory" in only:
        memory(console, args.memory_trials)
    if "agreement" in only:
        agreement(console, args.agreement_trials)


if __name__ == "__main__":
    main()
