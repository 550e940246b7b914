"""A run's data points from its log, and each calibration's covariance from them: the
points the calibration used, no more."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.testing import assert_allclose

from calib.io.camera_files import camera_from_dict, load_camera_covariance
from twin.campaign.check.calibration import calibration_covariance
from twin.campaign.records import CALIBRATION
from twin.logged_points import gathered, visit_points
from twin.record import read_log
from twin.runner import run_scenario

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
