"""Cameras placed by the fixed rule: the same seed gives the same cameras, each over free
floor, at its height, looking down by its tilt along the corridor."""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest
import yaml
from shapely.geometry import Point, box

from twin.planning.camera_layout import LEAST_SPACING, main, medial_axis, place_cameras
from twin.planning.floor_shapes import corridor_turn, floor_map
from twin.planning.sample_floor import write_office_floor


@pytest.fixture(scope="module")
def turn():
    return floor_map(corridor_turn(3.0, 90.0), source="turn")


def test_the_same_seed_places_the_same_cameras(turn):
    a = place_cameras(turn, seed=3)
    assert a == place_cameras(turn, seed=3)
    assert a != place_cameras(turn, seed=4)


def test_cameras_hang_over_the_free_floor_at_height_looking_down_by_the_tilt(turn):
    cams = place_cameras(turn, seed=0, height=3.0, tilt_deg=30.0)
    assert 6 <= len(cams) <= 30
    xy = np.array([c["position"][:2] for c in cams])
    for c in cams:
        assert turn.free.contains(Point(c["position"][:2]))
        assert c["position"][2] == 3.0
        d = np.asarray(c["view_direction"])
        assert np.linalg.norm(d) == pytest.approx(1.0, abs=1e-5)
        assert math.degrees(math.asin(-d[2])) == pytest.approx(30.0, abs=1e-4)
    # The narrowed spacing still keeps the cameras apart (grid cells of 0.1 m aside).
    gaps = np.linalg.norm(xy[:, None] - xy[None], axis=2) + 1e3 * np.eye(len(cams))
    assert gaps.min() >= LEAST_SPACING - 0.15


def test_cameras_on_a_straight_corridor_look_along_it_from_its_middle():
    floor = floor_map(box(0.0, -1.5, 30.0, 1.5), source="straight")
    cams = place_cameras(floor, seed=1, least=2, most=4)
    assert 2 <= len(cams) <= 4
    # Away from the ends (where the medial axis branches to the corners), on the middle
    # line, looking along the corridor towards its longer part.
    middle = [c for c in cams if 2.5 < c["position"][0] < 27.5]
    assert middle
    for c in middle:
        x, y, _ = c["position"]
        d = np.asarray(c["view_direction"])
        assert abs(y) <= 0.1
        along = math.copysign(math.cos(math.radians(30.0)), 15.0 - x)
        assert d[0] == pytest.approx(along, abs=1e-5)


def test_the_medial_axis_of_a_rectangle_runs_along_its_middle():
    points, clear = medial_axis(box(0.0, 0.0, 20.0, 4.0))
    middle = points[(points[:, 0] > 3.0) & (points[:, 0] < 17.0)]
    assert middle.size
    assert np.all(np.abs(middle[:, 1] - 2.0) <= 0.1)
    assert clear.max() == pytest.approx(2.0, abs=0.1)


def test_a_floor_no_robot_fits_on_is_refused():
    with pytest.raises(ValueError, match="no floor is"):
        place_cameras(floor_map(box(0.0, 0.0, 1.0, 1.0), source="closet"))
    with pytest.raises(ValueError, match="least <= most"):
        place_cameras(floor_map(box(0.0, 0.0, 9.0, 9.0)), least=5, most=2)


def test_a_camera_on_a_stub_of_the_axis_looks_down_the_floor_not_at_the_wall():
    # The axis runs across a corridor 1.6 m wide (a stub at a junction): along it, the
    # walls stand 0.8 m away; the camera looks along the corridor's 10 m instead.
    from shapely.geometry import box

    from twin.planning.camera_layout import OPEN_VIEW, _direction

    free = box(-0.8, -10.0, 0.8, 10.0)
    stub = np.array([[-0.5, 0.0], [0.0, 0.0], [0.5, 0.0]])
    d = _direction(stub, np.zeros(2), free)
    assert abs(d[0]) < 1e-9
    assert abs(abs(d[1]) - 1.0) < 1e-9
    # Where the axis itself runs free far enough, the camera looks along it.
    long = box(-10.0, -0.8, 10.0, 0.8)
    along = _direction(stub, np.array([-OPEN_VIEW, 0.0]), long)
    np.testing.assert_allclose(along, [1.0, 0.0], atol=1e-9)


def test_the_command_writes_the_cameras_and_logs_them_without_printing(tmp_path, caplog, capsys):
    grid, _ = write_office_floor(tmp_path, 20.0, 20.0, cameras=2)
    out = tmp_path / "placed.yaml"
    with caplog.at_level(logging.INFO, logger="twin.planning.camera_layout"):
        assert main([str(grid), "--out", str(out), "--seed", "1"]) == 0
    cameras = yaml.safe_load(out.read_text())
    assert len(cameras) >= 1
    assert caplog.messages == [f"wrote {len(cameras)} cameras to {out}"]
    assert capsys.readouterr().out == ""
