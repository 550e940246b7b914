"""The global adjustment at the batch fidelity (``twin montecarlo --adjust``): each trial's
network as the executor measured it, adjusted as a run's log is."""

from __future__ import annotations

import numpy as np
import pytest

from tests.twin.campaign.loop_scenario import loop_scenario
from twin.batch.execute import BatchRun
from twin.batch.network import adjust_trials
from twin.batch.steps import record_plan

VISITS = [("cam1", 1), ("cam1", 2)]


@pytest.fixture(scope="module")
def plan():
    sc = loop_scenario()
    return record_plan(sc.model_copy(update={"control_points": ()}))


def _adjusted(plan, run):
    px = run.advertised_led_px if run.noise.led_detection_px else {"cam1": 1e-3}
    return adjust_trials(run.network, run.trials, plan.cameras, px, 0.0, VISITS)


def test_without_noise_each_trial_is_adjusted_onto_the_truth(plan):
    run = BatchRun(plan, [1, 2], noise=plan.scenario.without_noise().noise, record_network=True)
    run.run()
    adjusted = _adjusted(plan, run)
    for key in VISITS:
        assert np.all(adjusted[key].position_error < 1e-6), adjusted[key].position_error
        assert np.all(adjusted[key].rotation_error < 1e-8)


def test_with_noise_the_revisit_improves_and_the_covariance_holds(plan):
    # 40 trials of the loop: camera 1's second calibration, sequential against adjusted,
    # and the adjustment's predicted RMS against its spread. The sampling spread of an RMS
    # over 40 trials is about 8 %; the bounds leave several times that.
    run = BatchRun(plan, list(range(100, 140)), record_network=True)
    outcome = run.run()
    adjusted = _adjusted(plan, run)
    second = adjusted[("cam1", 2)]
    sequential = outcome.calibrations[("cam1", 2)].position_error
    rms = float(np.sqrt(np.mean(second.position_error**2)))
    assert rms < 0.6 * float(np.sqrt(np.mean(sequential**2)))
    predicted = float(np.sqrt(np.mean(second.predicted**2)))
    assert 0.7 < rms / predicted < 1.4
    # One camera: both visits hold the same adjusted camera.
    np.testing.assert_array_equal(second.position_offset, adjusted[("cam1", 1)].position_offset)


def test_a_run_without_the_recorder_has_no_network(plan):
    assert BatchRun(plan, [1]).network is None


def test_the_childrens_survey_errors_are_adjusted_and_the_covariance_holds(plan):
    # Each child's marker 3 mm off its drawing a coordinate, known to the campaign: the
    # adjustment takes each child's survey error as an unknown (standard normal prior), so
    # its global test passes (chi2 / dof about 1; about 37 without them on the hall) and
    # the adjusted camera lies within its predicted covariance. 40 trials: an RMS is known
    # within about 8 %, the bounds leave several times that.
    from dataclasses import replace

    from twin.localization.adjustment import adjust_network
    from twin.scenario.overrides import with_values

    values = {"marker.survey_sigma_m": 0.003, "noise.marker_geometry_m": 0.003}
    surveyed = replace(plan, scenario=with_values(plan.scenario, values))
    run = BatchRun(surveyed, list(range(200, 240)), record_network=True)
    outcome = run.run()
    for k in range(3):
        builder, _ = run.network.network(k, run.advertised_led_px)
        network = builder.build()
        assert any(s.survey_level.size for s in network.led_sightings)
        adjusted = adjust_network(network)
        # dof of a few hundred: chi2 / dof has a spread of about 0.1.
        assert 0.6 < adjusted.variance_factor < 1.5, adjusted.variance_factor
    second = _adjusted(surveyed, run)[("cam1", 2)]
    rms = float(np.sqrt(np.mean(second.position_error**2)))
    predicted = float(np.sqrt(np.mean(second.predicted**2)))
    assert 0.7 < rms / predicted < 1.4
    sequential = outcome.calibrations[("cam1", 2)].position_error
    assert rms < 0.6 * float(np.sqrt(np.mean(sequential**2)))
