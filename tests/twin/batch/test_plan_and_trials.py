"""The batch fidelity executes the campaign's own plan: noise-free it recovers every camera
exactly, and each trial's result depends on its seed alone."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from tests.twin.batch.campaign_reference import campaign_calibration
from twin.batch.execute import BatchRun
from twin.batch.steps import Calibrate, Drive, Fix, Place, PlanSession, Point, record_plan
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
    out = BatchRun(plan, [1, 2], noise=quiet).run()
    assert len(out.calibrations) == len(plan.calibrations)
    for visit, v in out.calibrations.items():
        assert v.calibrated.all(), visit
        assert np.all(v.position_error < 1e-6), (visit, v.position_error)
        assert np.all(v.rotation_error < 1e-8), visit
    assert np.all(np.abs(out.parent_error) < 1e-6)
    assert not out.failures.any()


def test_a_trial_alone_gives_what_it_gives_in_a_batch(smoke_plan):
    seeds = [11, 12, 13, 14]
    batch = BatchRun(smoke_plan, seeds).run()
    alone = BatchRun(smoke_plan, [13]).run()
    ((key, v),) = batch.calibrations.items()
    w = alone.calibrations[key]
    assert v.position_error[2] == w.position_error[0]
    assert v.local_pixel[2] == w.local_pixel[0]
    np.testing.assert_array_equal(batch.parent_error[2], alone.parent_error[0])
    assert len(set(np.round(v.position_error, 12))) == len(seeds)  # trials differ


def test_the_batched_calibrations_are_the_campaigns(hall_plan):
    # The hall's five visits in twelve trials, each trial's data set calibrated again by
    # the campaign's scipy Tsai: the batched fit stops within a few 1e-6 of a standard
    # deviation of scipy's minimum (10 mm and 10 mrad: 1e-7 m and 1e-7 rad are 1e-5 of
    # one), so the metrics agree to a millionth.
    run = BatchRun(hall_plan, list(range(100, 112)))
    out = run.run()
    assert out.calibrations.keys() == {(c.camera, c.visit) for c in hall_plan.calibrations}
    for step in hall_plan.calibrations:
        key = (step.camera, step.visit)
        v, w = campaign_calibration(run, step), out.calibrations[key]
        assert w.calibrated.sum() >= 10, key
        np.testing.assert_array_equal(w.calibrated, v.calibrated, err_msg=str(key))
        close = np.testing.assert_allclose
        close(w.position_error, v.position_error, rtol=0, atol=1e-7, err_msg=str(key))
        close(w.rotation_error, v.rotation_error, rtol=0, atol=1e-7, err_msg=str(key))
        for name in ("local_pixel", "local_3d"):
            close(getattr(w, name), getattr(v, name), rtol=1e-6, err_msg=f"{key} {name}")
        close(w.predicted_calibration, v.predicted_calibration, rtol=1e-5, err_msg=str(key))


def test_a_stop_whose_led_leaves_the_image_is_given_up(smoke_plan):
    # LEDs as wide as the image: no stop sees all of its LEDs whole. Every trial gives up
    # every stop, counts each as a failure, and calibrates nothing.
    quiet = smoke_plan.scenario.without_noise().noise
    wide = dataclasses.replace(
        smoke_plan, led_radii={c: np.full(4, 10.0) for c in smoke_plan.led_radii}
    )
    out = BatchRun(wide, [1, 2], noise=quiet).run()
    stops = wide.count(Point)
    np.testing.assert_array_equal(out.failures, [stops, stops])
    (v,) = out.calibrations.values()
    assert not v.calibrated.any()
    np.testing.assert_array_equal(v.points, [0, 0])
    # With the LEDs' true radii every stop is seen without noise.
    out = BatchRun(smoke_plan, [1, 2], noise=quiet).run()
    assert not out.failures.any()
    (v,) = out.calibrations.values()
    (planned,) = smoke_plan.calibrations
    np.testing.assert_array_equal(v.points, [planned.points] * 2)


def test_a_trial_the_batched_fit_leaves_unconverged_is_calibrated_one_by_one(
    smoke_plan, monkeypatch
):
    # Held to one iteration, the batched fit converges nowhere: each trial is calibrated
    # by the campaign's own calibrate_tsai, and gives its numbers.
    import twin.batch.estimators as estimators

    real = estimators.calibrate_tsai_batch

    def one_step(*args, **kwargs):
        return real(*args, **{**kwargs, "max_iterations": 1})

    monkeypatch.setattr(estimators, "calibrate_tsai_batch", one_step)
    run = BatchRun(smoke_plan, [3, 4, 5])
    (v,) = run.run().calibrations.values()
    assert v.calibrated.all()
    (step,) = smoke_plan.calibrations
    np.testing.assert_array_equal(v.position_error, campaign_calibration(run, step).position_error)


def test_a_batch_advances_decision_by_decision(smoke_plan):
    # The campaign without noise asks its questions one by one; each answer gives the
    # steps until the next question, and a batch of trials executes them as they come:
    # with the strategy's answers, the same trials as the whole plan's, bit for bit.
    seeds = [21, 22, 23]
    whole = BatchRun(smoke_plan, seeds).run()
    with PlanSession(smoke_plan.scenario, "paper") as session:
        run = BatchRun(session.plan, seeds)
        questions = []
        while not session.done:
            questions.append(type(session.question).__name__)
            for step in session.answer(session.suggested()):
                run.step(step)
        assert [repr(s) for s in session.plan.steps] == [repr(s) for s in smoke_plan.steps]
    assert {"ReferenceCameras", "NextVisit", "NextLeg"} <= set(questions)
    out = run.outcome()
    ((key, v),) = whole.calibrations.items()
    np.testing.assert_array_equal(out.calibrations[key].position_error, v.position_error)
    np.testing.assert_array_equal(out.parent_error, whole.parent_error)


def test_the_callers_answers_decide_the_plan(smoke_plan):
    # Answering "no further visit" at the first chance ends the campaign before any visit:
    # the batch calibrates nothing and the parent has not moved.
    with PlanSession(smoke_plan.scenario, "paper") as session:
        run = BatchRun(session.plan, [1, 2])
        while not session.done:
            is_visit = type(session.question).__name__ == "NextVisit"
            for step in session.answer(None if is_visit else session.suggested()):
                run.step(step)
        assert not any(isinstance(s, (Calibrate, Fix)) for s in session.plan.steps)
        with pytest.raises(RuntimeError, match="no question to answer"):
            session.answer(None)
    out = run.outcome()
    assert out.calibrations == {}
    np.testing.assert_array_equal(out.distance, [0.0, 0.0])
