"""Trials of one batch that go their own ways (some steps, their own stops, a restart): each
gives what it gives alone, bit for bit."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from twin.batch.execute import BatchRun
from twin.batch.rows import execute_rows
from twin.batch.steps import Calibrate, Drive, record_plan
from twin.batch.streams import Draws
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
CORRIDOR = ROOT / "scenarios" / "corridor.toml"


@pytest.fixture(scope="module")
def corridor_plan():
    return record_plan(load_scenario(CORRIDOR), "paper")


def _state(run: BatchRun, row: int) -> dict[str, object]:
    """What a trial has come to: its estimates, truths, travel and calibrations."""
    assert run.last_estimate is not None
    out: dict[str, object] = {
        "parent": run.cps.parent.translation[row],
        "covariance": run.cps.parent.covariance[row],
        "last": run.last_estimate.translation[row],
        "truth": run.last_truth[row],
        "distance": run.distance[row],
        "failures": run.failures[row],
        "track": np.array(run.track(row)),
    }
    for name, robot in run.robots.items():
        out[f"{name} true"] = robot.true[row]
        out[f"{name} believed"] = robot.believed[row]
    for key, visit in run.visits.items():
        if visit.calibrated[row]:
            out[f"{key} error"] = visit.position_error[row]
            out[f"{key} world"] = visit.world_3d[row]
    return out


def _same(a: dict[str, object], b: dict[str, object]) -> bool:
    return a.keys() == b.keys() and all(
        np.array_equal(a[k], b[k], equal_nan=True)  # type: ignore[arg-type]
        for k in a
    )


def _alone(plan, seed: int, steps) -> dict[str, object]:
    run = BatchRun(plan, [seed])
    for step in steps:
        run.step(step)
    return _state(run, 0)


def test_rows_that_take_their_own_steps_give_what_they_give_alone(corridor_plan):
    plan = corridor_plan
    steps = plan.steps
    calibrations = [i for i, s in enumerate(steps) if isinstance(s, Calibrate)]
    assert calibrations, "the corridor's paper campaign calibrates"
    cut = calibrations[0] + 1
    # Row 1 drives its robots to stops of its own: every drive 20 cm further along x.
    moved = tuple(
        replace(s, believed=s.believed + np.array([0.2, 0.0, 0.0])) if isinstance(s, Drive) else s
        for s in steps[:cut]
    )
    run = BatchRun(plan, [11, 12, 13, 14])
    execute_rows(run, {0: steps, 1: moved, 2: steps[: cut // 2]})
    assert _same(_state(run, 0), _alone(plan, 11, steps))
    assert _same(_state(run, 1), _alone(plan, 12, moved))
    assert _same(_state(run, 2), _alone(plan, 13, steps[: cut // 2]))
    assert _same(_state(run, 3), _alone(plan, 14, ()))
    # A row started again with a new seed is a new trial; the others go on as they were.
    run.restart([2], [21])
    execute_rows(run, {2: steps[:cut], 3: steps[:cut]})
    assert _same(_state(run, 2), _alone(plan, 21, steps[:cut]))
    assert _same(_state(run, 3), _alone(plan, 14, steps[:cut]))
    assert _same(_state(run, 0), _alone(plan, 11, steps))


def test_bad_rows_are_refused(corridor_plan):
    run = BatchRun(corridor_plan, [1, 2])
    drive = next(s for s in corridor_plan.steps if isinstance(s, Drive))
    with pytest.raises(ValueError, match="distinct trials"):
        run.step(drive, [0, 0])
    with pytest.raises(ValueError, match="distinct trials"):
        run.step(drive, [2])
    other = next(s for s in corridor_plan.steps if isinstance(s, Drive) and s.robot != drive.robot)
    with pytest.raises(ValueError, match="one drive of one robot per row"):
        run.drive_rows([drive, other], [0, 1])
    with pytest.raises(ValueError, match="1 seeds for 2 rows"):
        run.restart([0, 1], [5])
    recording = BatchRun(corridor_plan, [1, 2], record_network=True)
    with pytest.raises(ValueError, match="every step for every trial"):
        recording.step(drive, [0])


@settings(max_examples=30, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.lists(st.integers(0, 3), min_size=1, max_size=4, unique=True), st.integers(1, 7)
        ),
        min_size=1,
        max_size=12,
    )
)
def test_each_trial_draws_its_own_sequence_whatever_the_rows(takes):
    seeds = [3, 5, 8, 13]
    draws = Draws(seeds, 4)
    got: list[list[float]] = [[] for _ in seeds]
    for rows, n in takes:
        values = draws.take(n, rows=np.array(rows))
        for i, k in enumerate(rows):
            got[k].extend(values[i].tolist())
    for k, seed in enumerate(seeds):
        alone = Draws([seed], 0)
        expected = alone.take(len(got[k]))[0] if got[k] else np.zeros(0)
        assert np.array_equal(np.array(got[k]), expected)
