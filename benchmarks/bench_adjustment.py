"""The global adjustment against the sequential CPS calibrations, by Monte Carlo at the
geometric fidelity, on the paper's hall (``paper_hall.toml``: the paper's own information,
cameras 2 and 1 calibrated twice) and on the same hall with its loop closed
(``paper_hall_closed.toml``: back to the start, a prism left there measured again).

Each trial runs the campaign once per scenario with the same seed and adjusts its log four
ways:

- ``weights``: each visit's camera on its own, no loop (cameras ``per_visit`` and nothing
  measured twice required): what weighing the LEDs' shared errors alone gives;
- ``per_visit``: each visit's camera on its own, tied through control points only;
- ``shared``: a camera visited twice is one camera (the paper's own information);

and prints, per visit: the RMS true position error of the sequential calibration and of
each adjustment, the adjustment's predicted RMS (its covariance) over the Monte-Carlo RMS,
and the repeatability (second minus first calibration of a camera, RMS of its length).

    .venv/bin/python benchmarks/bench_adjustment.py [--trials 300] [--workers 2] [--scenarios F ...]
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ("paper_hall.toml", "paper_hall_closed.toml")
MODES = ("weights", "per_visit", "shared")


def _offset(entry: dict[str, Any] | None) -> np.ndarray:
    if not entry or not entry.get("truth"):
        return np.full(3, np.nan)
    return np.asarray(entry["parameters"]["position_mm"]) - np.asarray(
        entry["truth"]["position_mm"]
    )


def _std(entry: dict[str, Any] | None) -> float:
    if not entry:
        return math.nan
    return 1e3 * math.sqrt(sum(entry["std"][k] ** 2 for k in "xyz"))


def trial(job: tuple[str, int]) -> dict[str, Any]:
    """One run of a scenario: per visit, the offsets from the truth (mm) and the predicted
    RMS (mm) of the sequential calibration and of each adjustment."""
    from twin.campaign.adjusted_results import adjusted_results, adjustment_settings
    from twin.campaign.network_log import network_from_log
    from twin.localization.adjustment import adjust_network
    from twin.record import read_log
    from twin.run.runner import run_scenario
    from twin.scenario import load_scenario

    name, seed = job
    sc = load_scenario(ROOT / "scenarios" / name)
    with tempfile.TemporaryDirectory() as tmp:
        results = run_scenario(sc, tmp, fidelity="geometric", seed=seed, report=False)
        messages = read_log(f"{tmp}/log.mcap").messages
    settings = adjustment_settings(sc)
    out: dict[str, Any] = {"seed": seed, "sequential": {}, "wall": {}}
    for c in results["calibrations"]:
        out["sequential"][(c["camera"], c["visit"])] = (_offset(c), math.nan)
    for mode in ("per_visit", "shared"):
        t0 = time.perf_counter()
        adj = adjusted_results(messages, cameras=mode, **settings)
        out["wall"][mode] = time.perf_counter() - t0
        out[mode] = {
            (c["camera"], c["visit"]): (_offset(c), _std(c)) for c in adj["adjusted_calibrations"]
        }
    # Weighing alone: per visit, no loop required (a control point, if any, left out).
    t0 = time.perf_counter()
    net, index = network_from_log(
        [m for m in messages if m.topic != "/campaign/control_sighting"],
        settings["pixel_noise_px"],
        cameras="per_visit",
        child_creep_m=settings["child_creep_m"],
    )
    adjusted = adjust_network(net, require_redundancy=False)
    out["wall"]["weights"] = time.perf_counter() - t0
    from calib.tsai import tsai_from_vector, tsai_reported

    truths = {c["camera"]: c["truth"] for c in results["calibrations"] if c.get("truth")}
    weights = {}
    for key in index.calibrations:
        c = index.camera_of(*key, "per_visit")
        size = tuple(int(v) for v in net.image_sizes[c])
        cam = tsai_from_vector(adjusted.cameras[c], size)
        _, cov = tsai_reported(adjusted.cameras[c], adjusted.camera_covariances[c], size)
        truth = np.asarray(truths[key[0]]["position_mm"])
        weights[key] = (1e3 * cam.position - truth, 1e3 * math.sqrt(np.trace(cov[8:, 8:])))
    out["weights"] = weights
    return out


def _rms(values: list[float]) -> float:
    a = np.asarray(values, dtype=float)
    a = a[np.isfinite(a)]
    return float(np.sqrt(np.mean(a**2))) if len(a) else math.nan


def _length(entries: dict[tuple[str, int], Any], cam: str) -> float:
    """Length of the second minus the first calibrated position of ``cam``, mm."""
    if (cam, 1) not in entries or (cam, 2) not in entries:
        return math.nan
    return float(np.linalg.norm(entries[(cam, 2)][0] - entries[(cam, 1)][0]))


def report(name: str, rows: list[dict[str, Any]]) -> None:
    visits = list(rows[0]["sequential"])
    print(f"\n{name}: {len(rows)} trials (same seeds), geometric fidelity")
    head = f"{'visit':12s} {'sequential':>10s}"
    for mode in MODES:
        head += f" {mode:>10s} {'pred/MC':>8s}"
    print(head + "   [RMS position error, mm]")
    for key in visits:
        seq = _rms([np.linalg.norm(r["sequential"][key][0]) for r in rows])
        line = f"{key[0]} v{key[1]:<7d} {seq:10.1f}"
        for mode in MODES:
            errs = [np.linalg.norm(r[mode][key][0]) for r in rows if key in r[mode]]
            pred = _rms([r[mode][key][1] for r in rows if key in r[mode]])
            mc = _rms(errs)
            line += f" {mc:10.1f} {pred / mc if mc else math.nan:8.2f}"
        print(line)
    cams = sorted({k[0] for k in visits if (k[0], 2) in visits})
    print("repeatability (second minus first calibration), RMS length, mm:")
    for cam in cams:
        seq = [r["sequential"] for r in rows]
        line = f"  {cam}: sequential " + f"{_rms([_length(s, cam) for s in seq]):.1f}"
        for mode in ("weights", "per_visit"):
            line += f", {mode} {_rms([_length(r[mode], cam) for r in rows]):.1f}"
        print(line + ", shared 0 (one camera)")
    walls = {m: np.mean([r["wall"][m] for r in rows]) for m in MODES}
    print(
        "adjustment wall time per trial, s: " + ", ".join(f"{m} {w:.2f}" for m, w in walls.items())
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=300)
    ap.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--master-seed", type=int, default=20080922)
    ap.add_argument("--scenarios", nargs="+", default=list(SCENARIOS), help="scenario files")
    args = ap.parse_args()
    from twin.montecarlo.seeds import trial_seed

    seeds = [trial_seed(args.master_seed, i) for i in range(args.trials)]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as pool:
        for name in args.scenarios:
            rows = list(pool.map(trial, [(name, s) for s in seeds]))
            report(name, rows)
    load = os.getloadavg()[0]
    print(f"\n{time.perf_counter() - t0:.0f} s with {args.workers} workers (load {load:.1f})")


if __name__ == "__main__":
    main()
