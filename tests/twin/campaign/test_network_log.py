"""A run's log as the adjustment's network, record by record: which records make which
stations, stands, sightings and LED stops, with the creep of each fix since a stand was
placed, the LED points a calibration used and the cameras' pixel noise."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calib.io.camera_files import camera_to_dict
from calib.rotation import rot_z
from calib.synthetic import paper_camera
from calib.tsai import tsai_vector
from twin.campaign.network_log import LogNetworkError, network_from_log
from twin.campaign.records import (
    CALIBRATION,
    CHILD_PLACED,
    CONTROL_SIGHTING,
    PARENT_FIX,
    POINT,
)

CREEP = 0.02
COV = np.diag([1e-6, 2e-6, 3e-6])
CAMERA = paper_camera(1)


def _m(topic: str, **data) -> SimpleNamespace:
    return SimpleNamespace(topic=topic, data=data)


def _fix(t: float, yaw: float, xyz, children=(), level=None) -> SimpleNamespace:
    n = len(children)
    return _m(
        PARENT_FIX,
        timestamp=t,
        yaw=yaw,
        translation=list(xyz),
        children=list(children),
        children_level=np.zeros((n, 3)) if level is None else level,
        children_covariance=np.tile(COV, (n, 1, 1)),
    )


def _placed(child: str, world) -> SimpleNamespace:
    return _m(CHILD_PLACED, child=child, point_level=[1.0, 0.0, 0.0], covariance=COV, world=world)


def _point(dataset: str, visit: int, n: int, start: float) -> SimpleNamespace:
    leds = np.column_stack([np.full(n, start), np.arange(n, dtype=float), np.zeros(n)])
    return _m(
        POINT,
        dataset=dataset,
        camera="cam1",
        visit=visit,
        child="child1",
        leds_world=leds,
        pixels=np.full((n, 2), start),
        leds_covariance=np.eye(3 * n) * start * 1e-6,
    )


def _calibration(visit: int, points: int, sigma_px: float) -> SimpleNamespace:
    return _m(
        CALIBRATION,
        camera="cam1",
        visit=visit,
        points=points,
        camera_model=camera_to_dict(CAMERA),
        sigma_px=sigma_px,
    )


def _log() -> list[SimpleNamespace]:
    """Station 0 with a reference set and two children placed; station 1 (both seen again,
    a control point, visit 1's stops); station 2 (child1 seen again, the control point
    again, visit 2's stops); child2 placed again and seen from station 3."""
    return [
        _point("visit", 1, 4, 99.0),  # before any fix: no station to hold it
        _fix(0.0, 0.0, [0, 0, 0]),
        _placed("child1", [1.0, 0.0, 0.0]),
        _placed("child2", [1.0, 1.0, 0.0]),
        _point("reference", 0, 4, 50.0),  # judges the result: left out
        _fix(10.0, 0.2, [2, 0, 0], ["child1", "child2"], np.array([[1, 2, 3], [4, 5, 6.0]])),
        _m(CONTROL_SIGHTING, name="prism", point_level=[3.0, 1.0, 0.0], covariance=COV),
        _point("visit", 1, 4, 1.0),
        _point("visit", 1, 4, 2.0),
        _point("visit", 1, 4, 3.0),
        _calibration(1, 10, 0.3),  # 10 of the 12 LED points: the last stop's first 2
        _fix(20.0, 0.4, [4, 0, 0], ["child1"]),
        _m(CONTROL_SIGHTING, name="prism", point_level=[1.0, 1.0, 0.0], covariance=COV),
        _point("visit", 2, 4, 5.0),
        _point("visit", 2, 4, 6.0),
        _point("visit", 2, 4, 7.0),  # beyond the 8 points the calibration used
        _calibration(2, 8, 0.2),
        _placed("child2", [5.0, 1.0, 0.0]),
        _fix(30.0, 0.5, [6, 0, 0], ["child2"]),
    ]


def test_each_record_makes_its_part_of_the_network():
    net, index = network_from_log(_log(), child_creep_m=CREEP)
    assert index.stations_time == (0.0, 10.0, 20.0, 30.0)
    assert_allclose(net.stations[2], [0.4, 4.0, 0.0, 0.0])
    # Targets: child1's stand, child2's first stand, the prism (from station 1), child2's
    # second stand (placed from station 2).
    assert net.target_labels == (
        "stand of child1",
        "stand of child2",
        "control point prism",
        "stand of child2",
    )
    c, s = np.cos(0.2), np.sin(0.2)
    assert_allclose(net.targets[2], [2 + 3 * c - s, 3 * s + c, 0.0])
    seen = [(p.station, p.target) for p in net.point_sightings]
    assert seen == [(0, 0), (0, 1), (1, 0), (1, 1), (1, 2), (2, 0), (2, 2), (2, 3), (3, 3)]
    assert_allclose(net.point_sightings[3].point_level, [4, 5, 6])
    # The creep: once per fix since the stand was placed; none on a control point.
    creep = [0, 0, 1, 1, 0, 2, 0, 0, 1]
    horizontal = np.diag([1.0, 1.0, 0.0])
    for p, n in zip(net.point_sightings, creep, strict=True):
        assert_allclose(p.covariance, COV + n * CREEP**2 * horizontal, rtol=1e-12)


def test_a_calibrations_stops_are_its_visits_first_points_from_their_stations():
    net, index = network_from_log(_log(), child_creep_m=CREEP)
    assert index.calibrations == (("cam1", 1), ("cam1", 2))
    assert index.camera_keys == (("cam1", 0),)  # one camera: it did not move
    assert index.calibration_stops == ((0, 1, 2), (3, 4))
    sizes = [len(s.pixels) for s in net.led_sightings]
    assert sizes == [4, 4, 2, 4, 4]
    assert [s.station for s in net.led_sightings] == [1, 1, 1, 2, 2]
    last = net.led_sightings[2]
    assert last.covariance_level.shape == (6, 6)
    assert_allclose(np.diag(last.covariance_level), 3e-6)
    # Turned back into the levelled frame of station 1 (yaw 0.2, at x = 2).
    assert_allclose(last.leds_level @ rot_z(0.2).T + [2, 0, 0], [[3, 0, 0], [3, 1, 0]], atol=1e-14)
    assert_allclose(net.cameras[0], tsai_vector(CAMERA))
    # The pixel noise: each camera's smallest calibration residual, unless given.
    assert net.pixel_noise_px.tolist() == [0.2]
    given, _ = network_from_log(_log(), 0.05)
    assert given.pixel_noise_px.tolist() == [0.05]
    named, _ = network_from_log(_log(), {"cam1": 0.07})
    assert named.pixel_noise_px.tolist() == [0.07]


def test_per_visit_cameras_hold_their_own_stops():
    net, index = network_from_log(_log(), cameras="per_visit")
    assert index.camera_keys == (("cam1", 1), ("cam1", 2))
    assert net.camera_labels == ("cam1 visit 1", "cam1 visit 2")
    assert [s.camera for s in net.led_sightings] == [0, 0, 0, 1, 1]
    assert index.camera_of("cam1", 2, "per_visit") == 1


def test_what_the_log_lacks_is_named():
    with pytest.raises(LogNetworkError, match="no CPS fix or no calibration"):
        network_from_log(_log()[:10])
    without_residuals = [
        m if m.topic != CALIBRATION else _calibration(m.data["visit"], 8, float("nan"))
        for m in _log()
    ]
    with pytest.raises(LogNetworkError, match="camera 'cam1': no pixel noise given"):
        network_from_log(without_residuals)
    with pytest.raises(ValueError, match="cameras must be one of"):
        network_from_log(_log(), cameras="both")
