"""One Monte-Carlo trial: the whole campaign with one seed, as rows of the trial table.

A trial runs :func:`twin.run.runner.run_scenario` in a temporary folder and turns its results
and log into one row per planned camera visit (a visit that was not calibrated has a row
with ``calibrated`` 0 and NaN errors), so that every trial has the same rows.
"""

from __future__ import annotations

import math
import tempfile
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from twin.montecarlo.prediction import predictions_from_log
from twin.montecarlo.sources import isolate
from twin.report.reading import planned_visits, skipped_why
from twin.scenario import Scenario

COLUMNS: dict[str, type] = {
    "config": str,
    "trial": int,
    "seed": int,
    "camera": str,
    "visit": int,
    "calibrated": int,
    "not_calibrated": str,
    "distance_travelled_m": float,
    "points": int,
    "position_error_mm": float,
    "rotation_error_deg": float,
    "position_dx_mm": float,
    "position_dy_mm": float,
    "position_dz_mm": float,
    "world_pixel_mean": float,
    "world_error_3d_mean_mm": float,
    "local_pixel_mean": float,
    "local_error_3d_mean_mm": float,
    "predicted_transfer_rms_mm": float,
    "predicted_calibration_rms_mm": float,
    "adjusted_position_error_mm": float,
    "adjusted_rotation_error_deg": float,
    "adjusted_position_dx_mm": float,
    "adjusted_position_dy_mm": float,
    "adjusted_position_dz_mm": float,
    "adjusted_predicted_rms_mm": float,
    "parent_final_dx_mm": float,
    "parent_final_dy_mm": float,
    "parent_final_dz_mm": float,
    "parent_predicted_sx_mm": float,
    "parent_predicted_sy_mm": float,
    "parent_predicted_sz_mm": float,
    "parent_distance_m": float,
    "failures": int,
    "failure_kinds": str,
}
"""The trial table's columns and their types (lengths in the unit their names say).
``not_calibrated``: why the visit gave no calibration (empty where it did);
``failure_kinds``: the trial's failures by kind, ``kind count; ...`` (the batch fidelity
counts its failed consistency tests and missed LEDs without kinds: empty)."""


@dataclass(frozen=True)
class TrialSpec:
    """What one trial runs.

    Attributes:
        scenario: the scenario with all its noise (the instruments advertise this noise).
        config: ``all`` or the noise source that alone is simulated.
        trial: 0-based index. seed: the trial's root seed.
        fidelity: ``geometric`` or ``render``.
        strategy: the campaign's strategy, by name.
    """

    scenario: Scenario
    config: str
    trial: int
    seed: int
    fidelity: str
    strategy: str = "paper"


class TrialFailed(RuntimeError):
    """A trial raised: the message names the trial, its seed and how to run it alone."""


@dataclass(frozen=True)
class TrialResult:
    """A finished trial: its rows and the wall time it took, s."""

    spec: TrialSpec
    rows: tuple[dict[str, Any], ...]
    wall_s: float


def run_trial(spec: TrialSpec) -> TrialResult:
    """Run one trial (in this process) and return its rows."""
    from twin.record import read_log
    from twin.run.runner import run_scenario

    t0 = time.perf_counter()
    scenario = isolate(spec.scenario, spec.config)
    with tempfile.TemporaryDirectory(prefix="twin-trial-") as tmp:
        try:
            results = run_scenario(
                scenario,
                tmp,
                fidelity=spec.fidelity,
                seed=spec.seed,
                report=False,
                advertised_noise=spec.scenario.noise,
                strategy=spec.strategy,
                cameras=False,
                foxglove=False,
            )
        except Exception as exc:
            alone = "" if spec.config == "all" else f" (with {spec.config} noise alone)"
            source = spec.scenario.source or "SCENARIO"
            raise TrialFailed(
                f"trial {spec.trial} of {spec.config!r} (seed {spec.seed}) failed: "
                f"{type(exc).__name__}: {exc}. It runs alone{alone} with: twin run "
                f"{source} --fidelity {spec.fidelity} --seed {spec.seed} "
                f"--strategy {spec.strategy}"
            ) from exc
        messages = read_log(f"{tmp}/log.mcap").messages
        pixel_noise = {
            c.name: spec.scenario.projected_led_px(c.name) for c in spec.scenario.cameras
        }
        predictions, final = predictions_from_log(messages, pixel_noise)
    rows = trial_rows(spec, results, predictions, final)
    return TrialResult(spec, tuple(rows), time.perf_counter() - t0)


def mm(value: Any) -> float:
    """Metres -> mm; None -> NaN."""
    return math.nan if value is None else 1e3 * float(value)


def _get(d: dict[str, Any] | None, key: str) -> float:
    return math.nan if d is None or d.get(key) is None else float(d[key])


def row_key(spec: TrialSpec, camera: str, visit: int) -> dict[str, str | int]:
    """The columns that name a row: the trial (configuration, index, seed) and the visit."""
    return {
        "config": spec.config,
        "trial": spec.trial,
        "seed": spec.seed,
        "camera": camera,
        "visit": visit,
    }


def offset_columns(offset_mm: Any) -> dict[str, float]:
    """The columns of a calibrated camera's (3,) centre minus the true one in W, mm (NaN
    where not calibrated): what the repeatability of a camera visited twice is made of."""
    return {f"position_d{axis}_mm": float(offset_mm[i]) for i, axis in enumerate("xyz")}


def _offset_mm(calibration: dict[str, Any] | None) -> Any:
    """(3,) calibrated minus true camera centre, mm, of a result's calibration entry."""
    if calibration is None or calibration.get("truth") is None:
        return np.full(3, np.nan)
    estimated = np.asarray(calibration["parameters"]["position_mm"], dtype=float)
    return estimated - np.asarray(calibration["truth"]["position_mm"], dtype=float)


def adjusted_columns(
    position_error_mm: float, rotation_error_deg: float, offset_mm: Any, predicted_mm: float
) -> dict[str, float]:
    """The columns of a visit's calibration in the global adjustment: its true position
    (mm) and rotation (deg) errors, its (3,) centre minus the true one (mm) and the
    adjustment's predicted RMS position error (mm, from its covariance); NaN for none."""
    return {
        "adjusted_position_error_mm": float(position_error_mm),
        "adjusted_rotation_error_deg": float(rotation_error_deg),
        **{f"adjusted_position_d{a}_mm": float(offset_mm[i]) for i, a in enumerate("xyz")},
        "adjusted_predicted_rms_mm": float(predicted_mm),
    }


def adjusted_entry_columns(entry: dict[str, Any] | None) -> dict[str, float]:
    """:func:`adjusted_columns` of a result's ``adjusted_calibrations`` entry (NaN where
    there is none)."""
    truth = entry.get("truth") if entry else None
    std = entry.get("std", {}) if entry else {}
    sigma = [float(std.get(k, math.nan)) for k in ("x", "y", "z")]
    return adjusted_columns(
        _get(truth, "position_error_mm"),
        _get(truth, "rotation_error_deg"),
        _offset_mm(entry),
        mm(math.sqrt(sum(v * v for v in sigma))),
    )


def failure_kinds(failures: Mapping[str, int]) -> str:
    """A trial's failures by kind as one cell: ``kind count; ...`` in the order of the
    kinds' names (empty where there are none)."""
    return "; ".join(f"{kind} {count}" for kind, count in sorted(failures.items()) if count)


def parent_columns(
    error_m: Any, std_m: Any, distance_m: float, failures: int, kinds: str = ""
) -> dict[str, float | int | str]:
    """The columns every row of a trial shares: the parent's final error (3,) and its
    predicted standard deviations (3,), m, its travel, m, and the trial's failures (their
    number, and ``kinds``: :func:`failure_kinds`)."""
    return {
        "parent_final_dx_mm": mm(error_m[0]),
        "parent_final_dy_mm": mm(error_m[1]),
        "parent_final_dz_mm": mm(error_m[2]),
        "parent_predicted_sx_mm": mm(std_m[0]),
        "parent_predicted_sy_mm": mm(std_m[1]),
        "parent_predicted_sz_mm": mm(std_m[2]),
        "parent_distance_m": float(distance_m),
        "failures": int(failures),
        "failure_kinds": kinds,
    }


def _why_not(skipped: Mapping[str, Any] | None) -> str:
    """Why a planned visit gave no calibration, from its ``skipped_visits`` entry."""
    if skipped is None:
        return "not_reached: the campaign ended before the visit"
    return skipped_why(skipped)


def trial_rows(
    spec: TrialSpec, results: dict[str, Any], predictions: list[Any], final: Any
) -> list[dict[str, Any]]:
    """The table rows of a trial from its results and predictions (one per planned visit)."""
    made = {(c["camera"], c["visit"]): c for c in results["calibrations"]}
    adjusted = {(c["camera"], c["visit"]): c for c in results.get("adjusted_calibrations", [])}
    predicted = {(p.camera, p.visit): p for p in predictions}
    err = final.error_m if final is not None else np.full(3, np.nan)
    std = np.sqrt(np.diag(final.covariance_m2)) if final is not None else np.full(3, np.nan)
    distance = final.distance_travelled_m if final is not None else math.nan
    failures = results["failures"]
    trial_level = parent_columns(
        err, std, distance, sum(failures.values()), failure_kinds(failures)
    )
    skipped = {(v["camera"], v["visit"]): v for v in results.get("skipped_visits", [])}
    rows = []
    for (camera, visit), _ in planned_visits(spec.scenario):
        c = made.get((camera, visit))
        p = predicted.get((camera, visit))
        world = c["errors"]["world"] if c else None
        local = c["errors"]["local"] if c else None
        truth = c["truth"] if c else None
        rows.append(
            {
                **row_key(spec, camera, visit),
                "calibrated": int(c is not None),
                "not_calibrated": "" if c else _why_not(skipped.get((camera, visit))),
                "distance_travelled_m": c["distance_travelled_m"] if c else math.nan,
                "points": c["points"] if c else 0,
                "position_error_mm": _get(truth, "position_error_mm"),
                "rotation_error_deg": _get(truth, "rotation_error_deg"),
                **offset_columns(_offset_mm(c)),
                "world_pixel_mean": _get(world, "pixel_mean"),
                "world_error_3d_mean_mm": _get(world, "error_3d_mean_mm"),
                "local_pixel_mean": _get(local, "pixel_mean"),
                "local_error_3d_mean_mm": _get(local, "error_3d_mean_mm"),
                "predicted_transfer_rms_mm": mm(p.transfer_rms_m) if p else math.nan,
                "predicted_calibration_rms_mm": mm(p.calibration_rms_m) if p else math.nan,
                **adjusted_entry_columns(adjusted.get((camera, visit))),
                **trial_level,
            }
        )
    return rows
