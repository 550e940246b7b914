"""The generated office floor: its size, its rooms reachable through their doors, its
cameras placed by the rule, the same for the same seed; bad sizes named."""

from __future__ import annotations

import logging
import math

import cv2
import numpy as np
import pytest

from twin.planning.sample_floor import (
    OFFICE_CAMERA_HEIGHT,
    OFFICE_TILT_DEG,
    RESOLUTION,
    main,
    office_floor,
)


def test_an_office_floor_is_one_piece_with_its_cameras_over_the_floor():
    floor = office_floor(60.0, 60.0, cameras=30, seed=0)
    assert floor.free.shape == (round(60 / RESOLUTION), round(60 / RESOLUTION))
    # Every room opens onto a corridor: the free floor is one piece.
    pieces, _ = cv2.connectedComponents(floor.free.astype(np.uint8), connectivity=4)
    assert pieces - 1 == 1
    assert 0.8 < floor.free.mean() < 0.95  # thin walls and a 1 m outer one
    assert len(floor.cameras) == 30
    assert len({c["name"] for c in floor.cameras}) == 30
    rows = floor.free.shape[0]
    for cam in floor.cameras:
        x, y, z = cam["position"]
        assert floor.free[rows - 1 - int(y / RESOLUTION), int(x / RESOLUTION)], cam["name"]
        assert z == OFFICE_CAMERA_HEIGHT
        dx, dy, dz = cam["view_direction"]
        down = math.degrees(math.atan2(-dz, math.hypot(dx, dy)))
        assert down == pytest.approx(OFFICE_TILT_DEG, abs=0.3)


def test_the_same_seed_gives_the_same_floor_and_rough_walls_only_narrow_it():
    a, b = office_floor(seed=3), office_floor(seed=3)
    assert np.array_equal(a.free, b.free)
    assert a.cameras == b.cameras
    assert not np.array_equal(a.free, office_floor(seed=4).free)
    rough = office_floor(seed=3, rough=0.5)
    assert not np.any(rough.free & ~a.free)
    assert 0.9 * a.free.sum() < rough.free.sum() < a.free.sum()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"cameras": 1}, "at least 2 cameras"),
        ({"width": 10.0}, "at least 20 x 20 m"),
        ({"cameras": 500}, "places for"),
    ],
)
def test_bad_office_floors_are_named(kwargs, message):
    with pytest.raises(ValueError, match=message):
        office_floor(**kwargs)


def test_the_command_writes_the_floor_and_logs_its_files_without_printing(tmp_path, caplog, capsys):
    with caplog.at_level(logging.INFO, logger="twin.planning.sample_floor"):
        assert main([str(tmp_path), "--cameras", "3"]) == 0
    written = sorted(p.name for p in tmp_path.iterdir())
    assert written == ["cameras.yaml", "map.png", "map.yaml"]
    assert caplog.messages == [f"wrote {tmp_path / 'map.yaml'} and {tmp_path / 'cameras.yaml'}"]
    assert capsys.readouterr().out == ""
