"""Data stops that show all LEDs (``campaign.data_stops = "all_leds"``) against stops chosen
for accuracy (``"accuracy"``), on the paper's hall: for each visit, the predicted std of the
calibrated camera's position (pixel noise 0.05 px plus the total station's point errors,
planned from the visit's station), the planning time, and the RMS true position error over a
few geometric runs of each setting. A visit whose accuracy stops take longer than
``PLAN_BUDGET_S`` to plan is marked ``slow`` and the benchmark exits 1.

    .venv/bin/python benchmarks/bench_data_stops.py [--runs 3] [--scenario PATH]
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from twin.campaign.plan.accurate_stops import (
    choose_stops,
    partial_view_stops,
    predicted_position_covariance,
)
from twin.campaign.plan.view_stops import body_points, view_stops
from twin.instruments.total_station import TotalStationSpec
from twin.run.runner import run_scenario
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]

PLAN_BUDGET_S = 1.0
"""Most wall seconds the accuracy stops of one visit may take to plan (measured 0.19-0.27 s on
the hall's visits, with another process on each core)."""


def _with(sc, data_stops):
    return sc.model_copy(
        update={"campaign": sc.campaign.model_copy(update={"data_stops": data_stops})}
    )


def predicted(sc):
    """Per visit: (camera, today's std mm, accuracy std mm, today's stops, accuracy stops,
    accuracy planning time s)."""
    spec = TotalStationSpec()
    rng = (spec.range_min, spec.range_max)
    marker = sc.marker.assembly()
    points = sc.campaign.station_points
    rows = []
    for visit in sc.calibration.visits:
        cam = sc.camera(visit.camera).tsai()
        parent = np.asarray(visit.station, dtype=float)
        inst = np.array([parent[0], parent[1], 0.0])
        need = math.ceil(points / len(marker.leds_body))
        today = view_stops(sc.space, marker, rng, cam, parent, 0.0, None)[:need]
        leds = [
            body_points(v.stop.xy[None], np.array([v.stop.yaw]), marker.leds_body, sc.space.floor_z)
            for v in today
        ]
        p_today = np.concatenate(leds).reshape(-1, 3)[:points]
        t0 = time.perf_counter()
        candidates = partial_view_stops(sc.space, marker, rng, cam, parent, 0.0, None)
        planned, _ = choose_stops(candidates, cam, inst, spec, points)
        took = time.perf_counter() - t0
        p_new = np.concatenate([s.leds_world[s.shown] for s in planned])[:points]
        std = [
            1e3 * math.sqrt(np.trace(predicted_position_covariance(cam, p, inst, spec)))
            for p in (p_today, p_new)
        ]
        rows.append((visit.camera, std[0], std[1], len(today), len(planned), took))
    return rows


def measured(sc, runs):
    """(visits, runs) true position errors, mm, of geometric runs with seeds 1..runs."""
    out = []
    for seed in range(1, runs + 1):
        with tempfile.TemporaryDirectory() as tmp:
            results = run_scenario(sc, tmp, fidelity="geometric", seed=seed, report=False)
        errors = {
            (c["camera"], c["visit"]): c["truth"]["position_error_mm"]
            for c in results["calibrations"]
        }
        out.append(errors)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--scenario", default=str(ROOT / "scenarios" / "paper_hall.toml"))
    args = parser.parse_args()
    sc = load_scenario(args.scenario)
    rows = predicted(sc)
    runs = {m: measured(_with(sc, m), args.runs) for m in ("all_leds", "accuracy")}
    print(f"{sc.name}: {args.runs} geometric runs per setting (seeds 1..{args.runs})")
    print(
        f"{'visit':<10}{'pred all_leds':>14}{'pred accuracy':>14}{'stops':>9}"
        f"{'RMS all_leds':>14}{'RMS accuracy':>14}{'plan s':>8}"
    )
    seen: dict[str, int] = {}
    slow = 0
    for camera, std_today, std_new, n_today, n_new, took in rows:
        seen[camera] = seen.get(camera, 0) + 1
        key = (camera, seen[camera])
        rms = []
        for m in ("all_leds", "accuracy"):
            e = np.array([r.get(key, math.nan) for r in runs[m]], dtype=float)
            rms.append(math.sqrt(np.nanmean(e**2)) if np.isfinite(e).any() else math.nan)
        print(
            f"{camera + ' #' + str(seen[camera]):<10}{std_today:>11.2f} mm{std_new:>11.2f} mm"
            f"{n_today:>4}/{n_new:<4}{rms[0]:>11.2f} mm{rms[1]:>11.2f} mm{took:>8.3f}"
            + ("  slow" if took > PLAN_BUDGET_S else "")
        )
        slow += took > PLAN_BUDGET_S
    if slow:
        print(f"{slow} visit(s) planned in more than {PLAN_BUDGET_S} s")
        raise SystemExit(1)


if __name__ == "__main__":
    main()
