"""A run's data points from its log, and each calibration's covariance from them: the
points the calibration used, no more."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.testing import assert_allclose

from calib.io.camera_files import camera_from_dict, load_camera_covariance
from twin.campaign.check.calibration import calibration_covariance
from twin.campaign.records import CALIBRATION
from twin.record import read_log
from twin.run.logged_points import gathered, visit_points
from twin.run.runner import run_scenario

ROOT = Path(__file__).resolve().parents[2]


def test_a_calibrations_covariance_comes_from_its_own_points(tmp_path):
    smoke = ROOT / "scenarios" / "smoke.toml"  # the paper's stops: 4 LEDs each
    run_scenario(smoke, tmp_path, fidelity="geometric", report=False, strategy="paper")
    messages = list(read_log(tmp_path / "log.mcap").messages)
    record = next(m.data for m in messages if m.topic == CALIBRATION)
    points = visit_points(gathered(messages), "cam1", 1, record["points"])
    # 70 points from stops of 4 LEDs: the last stop's first two.
    assert sum(len(p.point.pixels) for p in points) == record["points"] == 70
    assert len(points[-1].point.pixels) == 2
    assert points[-1].point.leds_covariance.shape == (6, 6)
    assert all(np.all(p.sigma_px > 0) for p in points)
    camera = camera_from_dict(record["camera_model"])
    written = load_camera_covariance(tmp_path / "cameras" / "cam1_visit1.json")
    assert_allclose(written, calibration_covariance(camera, points), rtol=1e-12)


def test_a_surveyed_markers_error_is_in_the_prediction_and_the_camera_file(tmp_path):
    # Each child's assembly 3 mm off its drawing a coordinate, and the campaign told so:
    # every data point carries its loading on the child's survey error (the same error at
    # every stop), and both the prediction and the camera file's covariance hold it. The
    # same log read without the loadings predicts a fraction of the error.
    import dataclasses

    from calib.camera_covariance import CAMERA_PARAMETERS
    from twin.montecarlo.prediction import predictions_from_log
    from twin.scenario import load_scenario
    from twin.scenario.overrides import with_values

    values = {"marker.survey_sigma_m": 0.003, "noise.marker_geometry_m": 0.003}
    smoke = with_values(load_scenario(ROOT / "scenarios" / "smoke.toml"), values)
    results = run_scenario(smoke, tmp_path, fidelity="geometric", report=False, seed=3)
    messages = list(read_log(tmp_path / "log.mcap").messages)
    record = next(m.data for m in messages if m.topic == CALIBRATION)
    points = visit_points(gathered(messages), "cam1", 1, record["points"])
    for p in points:
        assert p.point.survey_loading.shape == (3 * len(p.point.pixels), 12)
    (surveyed,), _ = predictions_from_log(messages, 0.05)
    bare = [
        dataclasses.replace(m, data={**m.data, "survey_loading": []})
        if m.topic == "/campaign/point"
        else m
        for m in messages
    ]
    (without,), _ = predictions_from_log(bare, 0.05)
    assert surveyed.calibration_rms_m > 3 * without.calibration_rms_m
    # This run's camera error lies within the survey-aware prediction (and is far beyond
    # the other one).
    error = results["calibrations"][0]["truth"]["position_error_mm"] * 1e-3
    assert error < 3 * surveyed.rms_m
    assert error > 3 * without.rms_m
    written = load_camera_covariance(tmp_path / "cameras" / "cam1_visit1.json")
    camera = camera_from_dict(record["camera_model"])
    assert_allclose(written, calibration_covariance(camera, points), rtol=1e-12)
    position = [CAMERA_PARAMETERS.index(k) for k in ("x", "y", "z")]
    assert np.sqrt(np.trace(written[np.ix_(position, position)])) > 3 * without.calibration_rms_m
