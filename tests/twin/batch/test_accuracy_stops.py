"""The batch fidelity with ``campaign.data_stops = "accuracy"``: each stop replayed with the
LEDs its noise-free plan found, the missing LEDs giving no point and no pixel residual."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from calib.io.camera_files import camera_to_dict
from tests.twin.batch.campaign_reference import campaign_calibration
from twin.batch.estimators import calibrate, coordinate_rows, points_effect
from twin.batch.execute import BatchRun
from twin.batch.steps import DataSetDone, Point, record_plan
from twin.montecarlo.prediction import points_variance
from twin.scenario import load_scenario
from twin.scenario.overrides import with_values

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"


@pytest.fixture(scope="module")
def accuracy_plan():
    return record_plan(with_values(load_scenario(SMOKE), {"campaign.data_stops": "accuracy"}))


def test_the_plan_holds_the_leds_each_stop_showed(accuracy_plan):
    points = [s for s in accuracy_plan.steps if isinstance(s, Point)]
    assert all(p.partial for p in points), "stops chosen for accuracy take partial points"
    assert all(p.leds and list(p.leds) == sorted(set(p.leds)) for p in points)
    assert all(0 <= k < 4 for p in points for k in p.leds)
    assert any(len(p.leds) < 4 for p in points), "the smoke camera's stops show some LEDs"
    # The data set is the first LED points of its stops, as the campaign counted them.
    (done,) = [
        s for s in accuracy_plan.steps if isinstance(s, DataSetDone) and s.dataset == "visit"
    ]
    (cal,) = accuracy_plan.calibrations
    shown = sum(len(p.leds) for p in points if p.dataset == "visit")
    assert cal.points == done.points == min(shown, accuracy_plan.scenario.campaign.station_points)


def test_without_noise_the_camera_is_recovered_exactly(accuracy_plan):
    quiet = accuracy_plan.scenario.without_noise().noise
    out = BatchRun(accuracy_plan, [1, 2], noise=quiet).run()
    (v,) = out.calibrations.values()
    (cal,) = accuracy_plan.calibrations
    assert v.calibrated.all()
    np.testing.assert_array_equal(v.points, [cal.points] * 2)
    assert np.all(v.position_error < 1e-6), v.position_error
    assert np.all(v.rotation_error < 1e-8), v.rotation_error
    assert not out.failures.any()


def test_the_batched_calibrations_are_the_campaigns(accuracy_plan):
    # Trials that lose some of a stop's LEDs calibrate on fewer points; the prediction
    # places each point in its stop's block by its LED.
    run = BatchRun(accuracy_plan, list(range(40, 52)))
    (w,) = run.run().calibrations.values()
    (step,) = accuracy_plan.calibrations
    v = campaign_calibration(run, step)
    assert w.calibrated.all()
    assert len(set(w.points)) > 1, "trials that gave up some LEDs"
    close = np.testing.assert_allclose
    close(w.position_error, v.position_error, rtol=0, atol=1e-7)
    close(w.local_pixel, v.local_pixel, rtol=1e-6)
    close(w.predicted_calibration, v.predicted_calibration, rtol=1e-5)


def _points_part(plan):
    """One noise-free trial's points part of the prediction, from the batch (with and
    without the stops' shared survey loadings) and from the campaign's records of its
    stops (:func:`twin.montecarlo.prediction.points_variance`); and those records."""
    quiet = plan.scenario.without_noise().noise
    run = BatchRun(plan, [5], noise=quiet)
    run.run()
    (cal,) = plan.calibrations
    (data,) = run.datasets[("visit", cal.camera, cal.visit)]  # every trial took it together
    points, pixels = data.arrays(cal.points)
    cams = calibrate(points, pixels, cal.nominal.image_size, cal.nominal)
    slots = data.slots()[: cal.points]
    got = np.trace(points_effect(cams, points, data.stops(), slots, data.shared())[0])
    alone = np.trace(points_effect(cams, points, data.stops(), slots)[0])
    stops = []
    for world, cov, leds, child, load in zip(
        data.points, data.covariances, data.leds, data.children, data.surveys, strict=True
    ):
        rows = coordinate_rows(leds[None])[0]
        stops.append(
            {
                "child": child,
                "leds_world": world[0],
                "leds_covariance": cov[0][np.ix_(rows, rows)],
                "survey_loading": load[0][rows] if load.size else [],
            }
        )
    want = points_variance(camera_to_dict(cams.cameras.camera(0)), stops, cal.points)
    return got, alone, want, stops


def test_the_points_part_of_the_prediction_is_the_campaigns(accuracy_plan):
    # The batch places each LED point in the block of its stop by its LED; the campaign's
    # prediction pads each stop's block of the LEDs it found. The same points give the same
    # variance.
    got, alone, want, stops = _points_part(accuracy_plan)
    assert len({len(s["leds_world"]) for s in stops}) > 1, "stops with fewer LEDs"
    assert got == alone  # the marker is known exactly
    np.testing.assert_allclose(got, want, rtol=1e-9)


@pytest.fixture(scope="module")
def surveyed_plan(accuracy_plan):
    """The plan with a marker known to 2 mm (the plan itself does not depend on it)."""
    values = {"marker.survey_sigma_m": 0.002, "noise.marker_geometry_m": 0.002}
    return dataclasses.replace(accuracy_plan, scenario=with_values(accuracy_plan.scenario, values))


def test_the_survey_part_of_the_prediction_is_the_campaigns(surveyed_plan):
    # Each stop's LEDs load on their child's surveying error (turned with the child): the
    # batch's layout of the loadings gives what the campaign's prediction gives from the
    # data points' survey_loading.
    got, alone, want, stops = _points_part(surveyed_plan)
    assert all(len(s["survey_loading"]) for s in stops)
    np.testing.assert_allclose(got, want, rtol=1e-9)
    # A 2 mm survey moves the camera by more than the shots do.
    assert got > 2 * alone


def test_the_batched_survey_part_is_the_campaigns(surveyed_plan):
    run = BatchRun(surveyed_plan, list(range(60, 66)))
    (w,) = run.run().calibrations.values()
    (step,) = surveyed_plan.calibrations
    v = campaign_calibration(run, step)
    assert w.calibrated.all()
    np.testing.assert_allclose(w.predicted_calibration, v.predicted_calibration, rtol=1e-5)


def test_a_missing_led_is_given_up_alone(accuracy_plan):
    # LED 0 as wide as the image: no trial finds it. With accuracy stops each stop that
    # showed it loses that LED only (one failure a stop); the other LEDs stay points.
    quiet = accuracy_plan.scenario.without_noise().noise
    radii = {c: np.array([10.0, *r[1:]]) for c, r in accuracy_plan.led_radii.items()}
    wide = dataclasses.replace(accuracy_plan, led_radii=radii)
    stops = [s for s in accuracy_plan.steps if isinstance(s, Point)]
    with_led0 = sum(0 in s.leds for s in stops)
    (cal,) = accuracy_plan.calibrations
    # The data set's LED points: (stop, LED) in order, the first cal.points of them.
    visit = [s for s in stops if s.dataset == "visit"]
    columns = [(s, k) for s in visit for k in s.leds][: cal.points]
    out = BatchRun(wide, [1, 2], noise=quiet).run()
    np.testing.assert_array_equal(out.failures, [with_led0, with_led0])
    (v,) = out.calibrations.values()
    np.testing.assert_array_equal(v.points, [sum(k != 0 for _, k in columns)] * 2)
    assert np.all(v.position_error < 1e-6)
    # The same LED at stops that must show every LED gives up every stop that held it.
    whole = tuple(
        dataclasses.replace(s, partial=False) if isinstance(s, Point) else s for s in wide.steps
    )
    out = BatchRun(dataclasses.replace(wide, steps=whole), [1], noise=quiet).run()
    (v,) = out.calibrations.values()
    assert out.failures[0] == with_led0
    kept = sum(0 not in s.leds for s, _ in columns)
    too_few = kept < accuracy_plan.scenario.campaign.min_points  # then not calibrated
    assert v.points[0] == (0 if too_few else kept)


@pytest.mark.parametrize(("strategy", "partial"), [("planned", True), ("paper", False)])
def test_the_strategy_decides_partial_points_whatever_the_scenario_says(strategy, partial):
    # The smoke scenario says data_stops = "all_leds"; the planned strategy chooses its
    # stops for accuracy and takes partial points there, and its trials must too (they gave
    # up whole stops, and calibrated nothing where noise moved an LED off the image).
    sc = load_scenario(SMOKE)
    assert sc.campaign.data_stops == "all_leds"
    points = [s for s in record_plan(sc, strategy).steps if isinstance(s, Point)]
    assert points
    assert {p.partial for p in points} == {partial}
