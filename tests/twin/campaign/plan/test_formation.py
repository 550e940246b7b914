"""The children's formation during a CPS leg."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from twin.campaign.plan.clearance import body_points, child_profile, passes_near
from twin.campaign.plan.formation import formation
from twin.campaign.plan.route import RoutePath
from twin.scenario import load_scenario

HALL = Path(__file__).resolve().parents[4] / "scenarios" / "paper_hall.toml"
RANGE = (1.3, 2200.0)
"""The instrument's range (Table I), m."""


@pytest.fixture(scope="module")
def hall():
    return load_scenario(HALL)


def test_the_child_that_waits_does_not_hide_the_one_measured_first(hall):
    # On the way east past the island: the parent at s = 26.3 m, the next station 4.6 m on.
    path = RoutePath(hall.route.waypoints)
    here, s_next = np.array([26.26, 0.0]), 30.84
    there = path.at(s_next)
    z, floor = 0.0, hall.space.floor_z
    cubes = np.asarray(hall.marker.cubes, dtype=float)
    form = hall.campaign.formation
    found = formation(hall.space, cubes, RANGE, path, s_next, here, there, 1.0, form, z)
    assert found is not None
    free_stops = found[1]
    # A child waiting right on the line of sight to where the far child would stop.
    far = free_stops[0]
    waiting = here + 0.3 * (np.asarray(far.xy) - here)
    found = formation(
        hall.space, cubes, RANGE, path, s_next, here, there, 1.0, form, z, waiting_xy=waiting
    )
    assert found is not None
    stops = found[1]
    assert not np.allclose(stops[0].xy, far.xy)
    inst = np.array([here[0], here[1], z])
    prisms = body_points(stops[0].xy, stops[0].yaw, cubes, floor)[0]
    assert not passes_near(inst, prisms, waiting, child_profile(floor)).any()
    blocked = body_points(far.xy, far.yaw, cubes, floor)[0]
    assert passes_near(inst, blocked, waiting, child_profile(floor)).any()
