"""Each trial's network from what the batch recorded, event by event: its stations and
stands with the creep of each fix, the LED stops of its calibrated visits (the LEDs it
found, the points the calibration used) and its camera started from its first successful
calibration."""

from __future__ import annotations

import numpy as np
from numpy.testing import assert_allclose

from calib.camera import TsaiCameras
from calib.rotation import rot_z
from calib.synthetic import paper_camera
from calib.tsai import tsai_vector
from twin.batch.network import Calibrated, NetworkRecorder

CREEP = 0.01
T = 2


def _stop(rng, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    world = rng.normal(size=(T, n, 3))
    a = rng.normal(size=(T, 3 * n, 3 * n))
    cov = 1e-6 * a @ np.swapaxes(a, 1, 2)
    pixels = rng.uniform(0, 300, (T, n, 2))
    return world, cov, pixels


def _recorded():
    """Two trials: stations 0, 1, 2; child c1 placed at 0, seen from 1 and 2; visit 1's
    two stops of 4 LEDs from station 1 (trial 1 misses LED 2 of the first), calibrated in
    trial 0 only, from 6 points; visit 2's stop from station 2, calibrated in both."""
    rng = np.random.default_rng(9)
    rec = NetworkRecorder()
    cov3 = np.tile(np.eye(3) * 1e-6, (T, 1, 1))
    rec.station(np.zeros(T), np.zeros((T, 3)))
    rec.stand("c1", np.ones((T, 3)), cov3, np.ones((T, 3)))
    rec.station(np.full(T, 0.1), np.full((T, 3), 0.5))
    rec.sight("c1", np.ones((T, 3)), cov3)
    stops = [_stop(rng, 4), _stop(rng, 4)]
    stops[0][0][1, 2] = np.nan
    stops[0][2][1, 2] = np.nan
    survey = rng.normal(size=(T, 12, 5))
    for world, cov, pixels in stops:
        rec.stop("cam1", 1, world, cov, pixels, "c1", survey)
    first = TsaiCameras.from_cameras([paper_camera(1), paper_camera(2)])
    rec.calibrated("cam1", 1, first, np.array([True, False]), 6)
    rec.station(np.full(T, 0.2), np.full((T, 3), 1.0))
    rec.sight("c1", np.ones((T, 3)), cov3)
    late = _stop(rng, 4)
    rec.stop("cam1", 2, *late, "c1", None)
    second = TsaiCameras.from_cameras([paper_camera(3), paper_camera(3)])
    rec.calibrated("cam1", 2, second, np.array([True, True]), 4)
    return rec, stops, survey, late


def test_a_trials_stands_carry_the_creep_of_each_fix():
    rec, *_ = _recorded()
    for k in range(T):
        builder, _ = rec.network(k, {"cam1": 0.2}, CREEP)
        net = builder.build()
        assert len(net.stations) == 3
        assert [(s.station, s.target) for s in net.point_sightings] == [(0, 0), (1, 0), (2, 0)]
        extra = [s.covariance[0, 0] - 1e-6 for s in net.point_sightings]
        assert_allclose(extra, [0.0, CREEP**2, 2 * CREEP**2], rtol=1e-9, atol=1e-20)


def test_the_calibrated_visits_stops_hold_the_points_the_trial_used():
    rec, stops, _, late = _recorded()
    builder, groups = rec.network(0, {"cam1": 0.2})
    net = builder.build()
    # Trial 0: visit 1 from 6 points (its first stop's 4, its second's first 2), visit 2
    # from 4; one camera, started from visit 1's calibration.
    assert groups == {("cam1", 1): (0, 1), ("cam1", 2): (2,)}
    assert [len(s.pixels) for s in net.led_sightings] == [4, 2, 4]
    assert [s.station for s in net.led_sightings] == [1, 1, 2]
    assert_allclose(net.cameras, [tsai_vector(paper_camera(1))])
    assert net.pixel_noise_px.tolist() == [0.2]
    second = net.led_sightings[1]
    np.testing.assert_array_equal(second.pixels, stops[1][2][0, :2])
    assert second.covariance_level.shape == (6, 6)
    assert second.survey_level.shape == (6, 5)
    assert net.led_sightings[2].survey_level.size == 0
    # Trial 1: visit 1 failed: no stops, and the camera starts from visit 2's.
    builder, groups = rec.network(1, {"cam1": 0.0})
    net = builder.build()
    assert groups == {("cam1", 2): (0,)}
    assert_allclose(net.cameras, [tsai_vector(paper_camera(3))])
    assert net.pixel_noise_px.tolist() == [1e-3]  # a floor for noise-free pixels
    assert_allclose(net.led_sightings[0].leds_level @ rot_z(0.2).T + 1.0, late[0][1], atol=1e-12)


def test_a_missed_led_leaves_the_stop_with_its_rows_and_columns():
    rec, stops, survey, _ = _recorded()
    rec.events = [e for e in rec.events if not (isinstance(e, Calibrated) and e.visit == 1)]
    rec.calibrated(
        "cam1",
        1,
        TsaiCameras.from_cameras([paper_camera(1)] * T),
        np.array([True, True]),
        8,
    )
    rec.events.insert(6, rec.events.pop())  # before station 2, where it was
    builder, groups = rec.network(1, {"cam1": 0.2})
    net = builder.build()
    first = net.led_sightings[groups[("cam1", 1)][0]]
    assert len(first.pixels) == 3  # LED 2 missed
    keep = [0, 1, 3]
    np.testing.assert_array_equal(first.pixels, stops[0][2][1, keep])
    rows = (3 * np.array(keep)[:, None] + np.arange(3)).ravel()
    turn = np.kron(np.eye(3), rot_z(0.1))
    assert_allclose(turn @ first.covariance_level @ turn.T, stops[0][1][1][np.ix_(rows, rows)])
    assert_allclose(turn @ first.survey_level, survey[1][rows])
    assert [len(s.pixels) for s in net.led_sightings] == [3, 4, 4]
