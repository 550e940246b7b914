"""ARCOS's angles, rounded to its units: headings in 4096ths of a turn (THPOS), turn rates
in whole deg/s (RVEL), speeds in mm/s (VEL), for negative and fractional values: the
nearest unit, the heading wrapped to one turn."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest
from hypothesis import given
from hypothesis import strategies as st

from twin.drivers.arcos import ArcosBase, Command
from twin.drivers.arcos.base import MIN_TURN_RATE
from twin.drivers.arcos.connection import ArcosPose
from twin.drivers.arcos.platforms import ANGLE_UNIT, PLATFORMS

P = PLATFORMS["p3dx"]
U = ANGLE_UNIT


@pytest.mark.parametrize(
    ("rad", "units"),
    [
        (0.0, 0),
        (math.pi / 2, 1024),
        (-math.pi / 2, -1024),
        (1.4 * U, 1),
        (1.6 * U, 2),
        (-1.4 * U, -1),
        (-1.6 * U, -2),
        (-0.4 * U, 0),
        (-1000.7 * U, -1001),
        (3 * math.pi / 2, -1024),  # wrapped to [-pi, pi)
        (-3 * math.pi / 2, 1024),
        (2 * math.pi + 3.3 * U, 3),
        (-2 * math.pi - 3.7 * U, -4),
        (math.pi, -2048),
        (-math.pi, -2048),
    ],
)
def test_a_heading_is_the_nearest_unit_of_the_wrapped_angle(rad, units):
    assert P.heading_units(rad) == units


@pytest.mark.parametrize(
    ("units", "rad"),
    [
        (0, 0.0),
        (1, U),
        (-1, -U),
        (1024, math.pi / 2),
        (-1024, -math.pi / 2),
        (3072, -math.pi / 2),
        (-3072, math.pi / 2),
        (2048, math.pi),
        (-2048, math.pi),
        (6144, math.pi),
        (4096 + 5, 5 * U),
    ],
)
def test_heading_units_read_back_as_the_angle_in_one_turn(units, rad):
    assert P.heading_rad(units) == pytest.approx(rad, abs=1e-12)


@given(st.floats(-20.0, 20.0, allow_nan=False))
def test_a_heading_is_off_by_half_a_unit_at_most(rad):
    back = P.heading_rad(P.heading_units(rad))
    off = math.remainder(back - rad, 2 * math.pi)
    assert abs(off) <= 0.5 * U + 1e-12
    assert -2048 <= P.heading_units(rad) <= 2048
    assert -math.pi < back <= math.pi


class _Link:
    """What the base needs of a connection: a clock, a pose, and a record of commands."""

    def __init__(self) -> None:
        self.clock = SimpleNamespace(now=lambda: 0.0)
        self.sent: list[tuple[int, int]] = []

    def pose(self) -> ArcosPose:
        return ArcosPose(0.0, 0.0, 0.0, 0.0, (0, 0, 0))

    def send(self, number: int, argument: int) -> None:
        self.sent.append((number, argument))


@pytest.mark.parametrize(
    ("v", "w_deg", "vel", "rvel"),
    [
        (0.2344, 1.4, 234, 1),
        (0.2346, 1.6, 235, 2),
        (-0.2344, -1.4, -234, -1),
        (-0.2346, -1.6, -235, -2),
        (-0.0004, -0.4, 0, 0),
        (0.0, -math.degrees(MIN_TURN_RATE), 0, -2),  # the slowest turn it asks for
        (0.0, math.degrees(MIN_TURN_RATE), 0, 2),
    ],
)
def test_a_velocity_command_is_the_nearest_mm_s_and_deg_s(v, w_deg, vel, rvel):
    link = _Link()
    base = ArcosBase(link, name="child1", start_pose=(0, 0, 0), max_speed=0.5, max_turn_rate=1.0)
    base._command(v, math.radians(w_deg))
    assert link.sent == [(Command.VEL, vel), (Command.RVEL, rvel)]


def test_a_turn_goes_the_shorter_way_at_no_less_than_the_slowest_rate():
    link = _Link()
    base = ArcosBase(link, name="child1", start_pose=(0, 0, 0), max_speed=0.5, max_turn_rate=1.0)
    assert base._turn(-1e-3) == -MIN_TURN_RATE
    assert base._turn(1e-3) == MIN_TURN_RATE
    assert base._turn(-2.0) == -1.0  # the turn-rate limit
    # A heading goal across +/-pi: the error is wrapped, the turn the short way.
    here, goal = [0.0, 0.0, math.pi - 0.1], [0.0, 0.0]
    v, w = base._control(here, goal, -math.pi + 0.1)
    assert v == 0.0
    assert w > 0.0
