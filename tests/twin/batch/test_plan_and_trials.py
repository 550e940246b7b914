"""The batch fidelity executes the campaign's own plan: noise-free it recovers every camera
exactly, and each trial's result depends on its seed alone."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from twin.batch.estimators import TrialByTrial
from twin.batch.execute import BatchRun
from twin.batch.plan import Calibrate, Drive, Fix, Place, Point, record_plan
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"
HALL = ROOT / "scenarios" / "paper_hall.toml"


@pytest.fixture(scope="module")
def hall_plan():
    return record_plan(load_scenario(HALL), "paper")


@pytest.fixture(scope="module")
def smoke_plan():
    return record_plan(load_scenario(SMOKE), "paper")


def test_the_plan_is_the_campaigns(hall_plan):
    # The paper's hall: five visits, 70 points each and two reference sets of 70, from
    # stops of four LEDs; CPS legs of the 85 m route.
    assert [(c.camera, c.visit) for c in hall_plan.calibrations] == [
        ("cam1", 1),
        ("cam2", 1),
        ("cam3", 1),
        ("cam2", 2),
        ("cam1", 2),
    ]
    assert all(c.points == 70 for c in hall_plan.calibrations)
    assert hall_plan.count(Point) >= (5 + 2) * 70 // 4
    assert hall_plan.count(Fix) >= 17
    assert hall_plan.count(Place) >= hall_plan.count(Point) + 2 * hall_plan.count(Fix)
    assert hall_plan.count(Drive) >= hall_plan.count(Place)
    assert isinstance(hall_plan.steps[-1], Calibrate)


@pytest.mark.parametrize("name", ["smoke", "hall"])
def test_without_noise_every_camera_is_recovered_exactly(name, smoke_plan, hall_plan):
    plan = smoke_plan if name == "smoke" else hall_plan
    quiet = plan.scenario.without_noise().noise
    out = BatchRun(plan, [1, 2], noise=quiet, estimators=TrialByTrial()).run()
    assert len(out.calibrations) == len(plan.calibrations)
    for visit, v in out.calibrations.items():
        assert v.calibrated.all(), visit
        assert np.all(v.position_error < 1e-6), (visit, v.position_error)
        assert np.all(v.rotation_error < 1e-8), visit
    assert np.all(np.abs(out.parent_error) < 1e-6)
    assert not out.failures.any()


def test_a_trial_alone_gives_what_it_gives_in_a_batch(smoke_plan):
    seeds = [11, 12, 13, 14]
    batch = BatchRun(smoke_plan, seeds, estimators=TrialByTrial()).run()
    alone = BatchRun(smoke_plan, [13], estimators=TrialByTrial()).run()
    ((key, v),) = batch.calibrations.items()
    w = alone.calibrations[key]
    assert v.position_error[2] == w.position_error[0]
    assert v.local_pixel[2] == w.local_pixel[0]
    np.testing.assert_array_equal(batch.parent_error[2], alone.parent_error[0])
    assert len(set(np.round(v.position_error, 12))) == len(seeds)  # trials differ
