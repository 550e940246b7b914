"""The generated floors: their shapes as built, and read back from a ROS map."""

import math

import numpy as np
import pytest
import shapely
from shapely.geometry import Point

from twin.planning import floor_shapes as fs
from twin.planning.maps import load_map


@pytest.mark.parametrize("turn", [0.0, 45.0, 90.0, 135.0])
def test_a_turned_corridor_is_as_wide_as_asked_along_both_legs(turn):
    width, leg = 2.4, 10.0
    free = fs.corridor_turn(width, turn, leg)
    a = math.radians(turn)
    mid_second = np.array([leg, 0.0]) + 0.5 * leg * np.array([math.cos(a), math.sin(a)])
    normal = np.array([-math.sin(a), math.cos(a)])
    for centre, side in (((0.5 * leg, 0.0), np.array([0.0, 1.0])), (mid_second, normal)):
        c = np.asarray(centre)
        assert free.contains(Point(*(c + (0.5 * width - 0.01) * side)))
        assert not free.contains(Point(*(c + (0.5 * width + 0.01) * side)))


def test_a_u_turn_comes_back_beside_itself_behind_a_wall():
    free = fs.u_turn(3.0, leg=10.0, gap=0.2)
    assert free.contains(Point(1.0, 0.0))
    assert free.contains(Point(1.0, 3.2))
    assert not free.contains(Point(1.0, 1.6))  # the wall between the ways
    assert free.area == pytest.approx(2 * 10.0 * 3.0 + 3.0 * 0.2 + 3.0 * 3.0, rel=0.05)


def test_a_dead_end_room_is_reached_only_through_its_door():
    free = fs.dead_end(2.4, length=16.0, room=(5.0, 4.0), door=1.0)
    strip = shapely.box(0.0, 1.25, 16.0, 1.35)  # inside the wall between corridor and room
    gap = strip.intersection(free)
    assert gap.bounds[2] - gap.bounds[0] == pytest.approx(1.0, abs=1e-6)
    assert strip.difference(free).area == pytest.approx((16.0 - 1.0) * 0.1, abs=1e-6)
    assert free.contains(Point(8.0, 3.0))  # the room


def test_two_rooms_join_only_at_the_door():
    free = fs.doorway(room=(8.0, 6.0), door=1.0)
    assert free.geom_type == "Polygon"
    assert free.buffer(-0.51).geom_type == "MultiPolygon"  # a 1 m door: cut at 0.51 m
    assert free.buffer(-0.49).geom_type == "Polygon"


def test_a_bad_turn_or_width_is_refused():
    with pytest.raises(ValueError, match="0 to 180"):
        fs.corridor_turn(2.4, 200.0)
    with pytest.raises(ValueError, match="width"):
        fs.corridor_turn(0.0, 90.0)


@pytest.mark.parametrize("flaws", [False, True])
def test_a_written_map_reads_back_as_the_floor(tmp_path, flaws):
    free = fs.corridor_turn(2.4, 90.0, leg=8.0)
    floor = load_map(fs.write_ros_map(free, tmp_path, resolution=0.05, flaws=flaws, seed=3))
    # A cell's worth around the outline, and the flaws' speckle (0.2 % of the cells).
    tolerance = free.length * 0.05 + (0.01 * free.area if flaws else 0.0)
    assert floor.free.symmetric_difference(free).area < tolerance
    assert floor.free.contains(Point(2.0, 0.0))
    assert floor.free.contains(Point(8.0, 6.0))
