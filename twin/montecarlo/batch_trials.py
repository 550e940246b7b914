"""Monte-Carlo trials at the batch fidelity: chunks of trials run at once
(:class:`twin.batch.execute.BatchRun`), each trial giving the rows of the trial table that
a geometric trial gives (:data:`twin.montecarlo.trial.COLUMNS`).

The plan is recorded once per run (:func:`twin.batch.steps.record_plan`) and shipped with
every chunk; a chunk holds trials of one configuration (one noise source, or all).
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from twin.batch.execute import BatchOutcome, BatchRun
from twin.batch.network import AdjustedVisits, adjust_trials
from twin.batch.steps import BatchPlan
from twin.montecarlo.sources import isolate
from twin.montecarlo.trial import (
    TrialFailed,
    TrialResult,
    TrialSpec,
    adjusted_columns,
    mm,
    offset_columns,
    parent_columns,
    row_key,
)
from twin.report.reading import planned_visits

DEFAULT_CHUNK_SIZE = 200
"""Trials one array holds at most by default: the hall's plan takes about 1 MB a trial at
once, so a chunk stays within a few hundred MB."""

BATCH_OMITS = (
    "decisions taken again under noise: re-aims after a lost lock or a wrong prism; a stop "
    "where an LED left the image is given up (at a stop chosen for accuracy only that "
    "LED) but not replaced by another; an LED that came into view at a stop planned "
    "without it is not used; the stops for accuracy are not planned again from the noisy "
    "estimates; a fix that failed its consistency test is not measured again (such a trial "
    "keeps its estimate and counts a failure). The geometric campaign's stops, planned "
    "again, are in many trials less spread than the plan's, which a marker's surveying "
    "error (the same at every stop) feels most: with the planned strategy on the smoke "
    "room the geometric camera errors are 1.16 times the batch's with an exact marker, "
    "1.25 times at 0.84 mm and 1.65 times at 3 mm (the paper's strategy: 1.07 at 3 mm)",
    "the injected faults of [faults]: lost_lock_rate, hidden_led_rate, unreachable (scenarios "
    "that set them are refused; a moved camera is modelled: its moved pose is the truth)",
    "the check shots at a child placed earlier (they only matter when it moved)",
    "the tilt of a child on a tilted floor patch (its marker moves in the plane)",
    "the occlusion of an LED by an obstacle or a person (the plan's stops were chosen in "
    "the clear)",
    "control points ([[control_points]]): not measured; with --adjust each trial's "
    "adjustment ties a camera's visits together but no loop through a control point",
)
"""What the batch fidelity leaves out; the geometric fidelity keeps it (``montecarlo.json``
and docs/montecarlo.md, under Fidelities, say so too)."""


@dataclass(frozen=True)
class BatchChunk:
    """Trials of one configuration run together.

    Attributes:
        plan: the campaign's plan. specs: the trials (one configuration).
        adjust: also adjust each trial's whole network (:mod:`twin.batch.network`).
    """

    plan: BatchPlan
    specs: tuple[TrialSpec, ...]
    adjust: bool = False


def default_chunk_size(trials: int, workers: int) -> int:
    """Trials a chunk holds when the user did not say: as many as shares ``trials`` among
    ``workers`` evenly, at most :data:`DEFAULT_CHUNK_SIZE`."""
    return max(1, min(DEFAULT_CHUNK_SIZE, math.ceil(trials / max(workers, 1))))


def chunks(
    plan: BatchPlan, specs: Iterable[TrialSpec], size: int, adjust: bool = False
) -> Iterator[BatchChunk]:
    """``specs`` in chunks of at most ``size`` consecutive trials of one configuration, in
    order, taken from ``specs`` as they are needed (an iterator of any length holds at most
    one chunk in memory)."""
    if size < 1:
        raise ValueError(f"a chunk holds at least 1 trial, got {size}")
    for _, group in itertools.groupby(specs, key=lambda spec: spec.config):
        while batch := tuple(itertools.islice(group, size)):
            yield BatchChunk(plan, batch, adjust)


def _adjusted_columns(v: AdjustedVisits | None, k: int) -> dict[str, float]:
    """The adjusted columns of trial ``k`` of a visit (NaN without an adjustment)."""
    if v is None:
        return adjusted_columns(math.nan, math.nan, np.full(3, math.nan), math.nan)
    return adjusted_columns(
        mm(v.position_error[k]),
        math.degrees(v.rotation_error[k]),
        1e3 * v.position_offset[k],
        mm(v.predicted[k]),
    )


def check_batch_scenario(plan_scenario: Any) -> None:
    """Refuse what the batch fidelity cannot run.

    Raises:
        ValueError: a scenario that injects faults (the batch has no faults to inject).
            A moved camera (``[[faults.moved_cameras]]``) runs: the noise-free plan
            records the camera where the world holds it, the truth the trials are
            measured against.
    """
    faults = plan_scenario.faults
    if faults.lost_lock_rate or faults.hidden_led_rate or faults.unreachable:
        raise ValueError(
            f"the batch fidelity injects no faults, and {plan_scenario.source or 'the scenario'} "
            "sets [faults]; run it with --fidelity geometric"
        )


def run_batch_chunk(chunk: BatchChunk) -> list[TrialResult]:
    """Run one chunk of trials at once; the rows of each, in the chunk's order."""
    t0 = time.perf_counter()
    specs = chunk.specs
    config = specs[0].config
    try:
        simulated = isolate(chunk.plan.scenario, config)
        led_px = {c.name: simulated.projected_led_px(c.name) for c in simulated.cameras}
        run = BatchRun(
            chunk.plan,
            [s.seed for s in specs],
            noise=simulated.noise,
            led_px=led_px,
            record_network=chunk.adjust,
        )
        outcome = run.run()
        adjusted = _adjusted(chunk, run) if chunk.adjust else {}
    except Exception as exc:
        first, last = specs[0].trial, specs[-1].trial
        raise TrialFailed(
            f"trials {first}-{last} of {config!r} at the batch fidelity failed: "
            f"{type(exc).__name__}: {exc}"
        ) from exc
    wall = (time.perf_counter() - t0) / len(specs)
    return [
        TrialResult(spec, tuple(_rows(spec, outcome, k, adjusted)), wall)
        for k, spec in enumerate(specs)
    ]


def _adjusted(chunk: BatchChunk, run: BatchRun) -> dict[tuple[str, int], AdjustedVisits]:
    """Each trial's global adjustment, per visit (weighed by the advertised noise, as the
    estimators weigh)."""
    sc = chunk.plan.scenario
    assert run.network is not None
    return adjust_trials(
        run.network,
        run.trials,
        chunk.plan.cameras,
        run.advertised_led_px,
        sc.campaign.child_creep_m,
        [key for key, _ in planned_visits(sc)],
    )


def _why_not(unplanned: bool) -> str:
    """Why a planned visit of a batch trial gave no calibration: the noise-free campaign
    did not calibrate it (no trial does), or this trial's data fell short."""
    if unplanned:
        return "not_in_plan: the noise-free campaign did not calibrate the visit"
    return "not_calibrated: too few points, or the calibration did not converge"


def _rows(
    spec: TrialSpec,
    outcome: BatchOutcome,
    k: int,
    adjusted: dict[tuple[str, int], AdjustedVisits] | None = None,
) -> list[dict[str, Any]]:
    """The table rows of trial ``k`` of a batch (one per planned visit)."""
    std = np.sqrt(np.diag(outcome.parent_covariance[k]))
    trial_level = parent_columns(
        outcome.parent_error[k], std, outcome.distance[k], outcome.failures[k]
    )
    rows = []
    for (camera, visit), _ in planned_visits(spec.scenario):
        v = outcome.calibrations.get((camera, visit))
        made = v is not None and bool(v.calibrated[k])
        rows.append(
            {
                **row_key(spec, camera, visit),
                "calibrated": int(made),
                "not_calibrated": "" if made else _why_not(v is None),
                "distance_travelled_m": float(v.distance[k]) if made else math.nan,
                "points": int(v.points[k]) if made else 0,
                "position_error_mm": mm(v.position_error[k]) if made else math.nan,
                "rotation_error_deg": math.degrees(v.rotation_error[k]) if made else math.nan,
                **offset_columns(1e3 * v.position_offset[k] if made else np.full(3, np.nan)),
                "world_pixel_mean": float(v.world_pixel[k]) if made else math.nan,
                "world_error_3d_mean_mm": mm(v.world_3d[k]) if made else math.nan,
                "local_pixel_mean": float(v.local_pixel[k]) if made else math.nan,
                "local_error_3d_mean_mm": mm(v.local_3d[k]) if made else math.nan,
                "predicted_transfer_rms_mm": mm(v.predicted_transfer[k]) if made else math.nan,
                "predicted_calibration_rms_mm": (
                    mm(v.predicted_calibration[k]) if made else math.nan
                ),
                **_adjusted_columns((adjusted or {}).get((camera, visit)), k),
                **trial_level,
            }
        )
    return rows
