"""Automatic aim: lock, miss, wrong prism, blocked line of sight, out of range."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from twin.instruments.aim import angles_from_direction, auto_aim
from twin.instruments.errors import (
    FailureReason,
    InstrumentError,
    LineOfSightBlockedError,
    NoPrismInConeError,
    OutOfRangeError,
)
from twin.instruments.marker import MarkerAssembly
from twin.instruments.total_station import TotalStationSpec

SPEC = TotalStationSpec()


def child_cubes(distance, heading=0.0):
    """The default marker's three cubes on a child ``distance`` m ahead, instrument frame."""
    c, s = np.cos(heading), np.sin(heading)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    return MarkerAssembly().cubes_body @ rot.T + [distance, 0.0, -0.75]


def test_locks_onto_the_prism_it_is_pointed_at():
    cubes = child_cubes(10.0)
    for i in range(3):
        assert auto_aim(cubes, cubes[i], SPEC) == i


def test_locks_within_the_cone_despite_a_pointing_error():
    prism = np.array([[20.0, 0.0, 0.0]])
    pointing = [20.0, 20.0 * np.tan(np.radians(4.9)), 0.0]
    assert auto_aim(prism, pointing, SPEC) == 0


def test_misses_outside_the_cone():
    prism = np.array([[20.0, 0.0, 0.0]])
    pointing = [20.0, 20.0 * np.tan(np.radians(5.1)), 0.0]
    with pytest.raises(NoPrismInConeError) as info:
        auto_aim(prism, pointing, SPEC)
    assert info.value.reason is FailureReason.NO_PRISM_IN_CONE
    assert info.value.details["closest_angle"] == pytest.approx(np.radians(5.1))
    # a prism behind the instrument is never found
    with pytest.raises(NoPrismInConeError):
        auto_aim(-prism, prism[0], SPEC)


def test_picks_the_wrong_cube_when_the_prediction_is_closer_to_another_cube():
    # Seen from 100 m the three cubes (0.25-0.30 m apart) are 0.15-0.17 deg apart: all
    # inside the 5 deg cone. A prediction 60 % of the way from cube 0 to cube 1 locks cube 1.
    cubes = child_cubes(100.0)
    assert np.all(angles_from_direction(cubes, cubes[0]) < SPEC.aim_cone)
    predicted = cubes[0] + 0.6 * (cubes[1] - cubes[0])
    assert auto_aim(cubes, predicted, SPEC) == 1
    # 40 % of the way it still locks the right one.
    assert auto_aim(cubes, cubes[0] + 0.4 * (cubes[1] - cubes[0]), SPEC) == 0


def test_wrong_child_when_two_children_are_close_in_angle():
    near = np.array([[30.0, 0.0, 0.0]])  # a cube of the near child
    far = np.array([[60.0, 1.0, 0.0]])  # the wanted cube of the far child, 0.95 deg aside
    prisms = np.vstack([near, far])
    assert auto_aim(prisms, far[0], SPEC) == 1
    # A prediction 0.7 m off (0.67 deg from the far cube, 0.29 deg from the near one)
    # locks the near child: the wrong prism, reported as a normal lock.
    assert auto_aim(prisms, [60.0, 0.3, 0.0], SPEC) == 0


def test_blocked_line_of_sight():
    cubes = child_cubes(10.0)

    def nothing_visible(index, point):
        return False

    with pytest.raises(LineOfSightBlockedError) as info:
        auto_aim(cubes, cubes[0], SPEC, nothing_visible)
    assert info.value.reason is FailureReason.LINE_OF_SIGHT_BLOCKED
    assert info.value.details["blocked"] == (0, 1, 2)

    seen = []

    def cube0_hidden(index, point):
        seen.append(index)
        np.testing.assert_array_equal(point, cubes[index])
        return index != 0

    # cube 0 is hidden, so the instrument locks the next closest visible cube
    locked = auto_aim(cubes, cubes[0], SPEC, cube0_hidden)
    assert locked != 0
    assert sorted(seen) == [0, 1, 2]


@pytest.mark.parametrize("distance", [1.0, 2500.0])
def test_out_of_range(distance):
    prism = np.array([[distance, 0.0, 0.0]])
    with pytest.raises(OutOfRangeError) as info:
        auto_aim(prism, prism[0], SPEC)
    assert info.value.reason is FailureReason.OUT_OF_RANGE
    assert info.value.details["distance"] == pytest.approx(distance)
    assert isinstance(info.value, InstrumentError)


def test_an_out_of_range_prism_closer_in_angle_fails_the_shot():
    # A prism 1.0 m away (below the 1.3 m minimum) lies 0.5 deg from the pointing
    # direction, the wanted prism 10 m away 1 deg: the near one takes the lock and the shot
    # fails; the aim does not fall back to the measurable prism.
    near = 1.0 * np.array([np.cos(np.radians(0.5)), np.sin(np.radians(0.5)), 0.0])
    wanted = 10.0 * np.array([np.cos(np.radians(-1.0)), np.sin(np.radians(-1.0)), 0.0])
    with pytest.raises(OutOfRangeError) as info:
        auto_aim(np.array([near, wanted]), [1.0, 0.0, 0.0], SPEC)
    assert info.value.details["prism_index"] == 0
    # pointed closer to the wanted prism, it locks it
    assert auto_aim(np.array([near, wanted]), wanted, SPEC) == 1


def test_bad_input():
    with pytest.raises(ValueError, match="pointing"):
        auto_aim([[10.0, 0, 0]], [0.0, 0.0, 0.0], SPEC)
    with pytest.raises(ValueError, match="NaN"):
        auto_aim([[np.nan, 0, 0]], [1.0, 0.0, 0.0], SPEC)
    with pytest.raises(ValueError, match="shape"):
        auto_aim(np.zeros((0, 3)), [1.0, 0.0, 0.0], SPEC)


@settings(max_examples=100, deadline=None)
@given(
    points=st.lists(st.tuples(*[st.floats(-50.0, 50.0)] * 3), min_size=1, max_size=8),
    direction=st.tuples(*[st.floats(-5.0, 5.0)] * 3),
)
def test_angles_from_direction_are_those_of_the_cross_product(points, direction):
    p, u = np.array(points), np.array(direction)
    if np.linalg.norm(u) < 1e-3 or np.any(np.linalg.norm(p, axis=1) < 1e-3):
        return
    unit = u / np.linalg.norm(u)
    n = np.linalg.norm(p, axis=-1)
    cos = np.einsum("...i,i->...", p, unit) / n
    expected = np.arctan2(np.linalg.norm(np.cross(p, unit), axis=-1) / n, cos)
    assert np.array_equal(angles_from_direction(p, u), expected)
