"""The children's formation during a CPS leg."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import ArrayLike, NDArray

from calib.rotation import wrap_angle
from twin.campaign.plan.clearance import (
    body_points,
    child_profile,
    in_range,
    passes_near,
    robot_fits,
    sight_clear,
)
from twin.campaign.plan.formation import SIGHT_MARGIN, formation
from twin.campaign.plan.formation_checks import (
    FORMATION_CLEARANCE,
    MIN_SEPARATION,
    FormationChecks,
)
from twin.campaign.plan.occlusion import unhidden_yaw
from twin.campaign.plan.route import RoutePath
from twin.campaign.plan.stop import Stop
from twin.scenario import load_scenario
from twin.scenario.schema import Space

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


def _places_ok(
    space: Space, places: list[NDArray[np.float64]], stations: list[NDArray[np.float64]]
) -> bool:
    """Whether the children's (2,) places (m) are free, 1 m apart and 1 m from each
    instrument ((3,) positions, m)."""
    xy = np.array(places)
    if not robot_fits(space, xy, FORMATION_CLEARANCE).all():
        return False
    if np.linalg.norm(xy[0] - xy[1]) < 1.0:
        return False
    return all(np.min(np.linalg.norm(xy - inst[:2], axis=1)) >= 1.0 for inst in stations)


def _formation_ok(
    space: Space,
    stops: list[Stop],
    stations: list[NDArray[np.float64]],
    cubes: NDArray[np.float64],
    instrument_range: tuple[float, float],
    waiting_xy: ArrayLike | None = None,
    sight_margin: float = SIGHT_MARGIN,
) -> bool:
    """Whether the children's stops suit both stations, checked plainly, nothing kept: the
    definition :class:`FormationChecks` must answer as. Their headings already keep every
    prism clear of its own assembly (:func:`unhidden_yaw`)."""
    xy = np.array([s.xy for s in stops])
    if not _places_ok(space, list(xy), stations):
        return False
    floor = space.floor_z
    if waiting_xy is not None:
        far = body_points(stops[0].xy, stops[0].yaw, cubes, floor)[0]
        if passes_near(stations[0], far, waiting_xy, child_profile(floor)).any():
            return False
    for inst in stations:
        bearings = []
        for k, stop in enumerate(stops):
            pts = body_points(stop.xy, stop.yaw, cubes, floor)[0]
            d = np.linalg.norm(pts - inst, axis=1)
            if not in_range(d, instrument_range).all():
                return False
            if not sight_clear(space, inst, pts, sight_margin).all():
                return False
            other = xy[1 - k]
            if passes_near(inst, pts, other, child_profile(floor)).any():
                return False
            v = stop.xy - inst[:2]
            bearings.append(math.atan2(v[1], v[0]))
        sep = abs(wrap_angle(bearings[0] - bearings[1]))
        if sep < MIN_SEPARATION:
            return False
    return True


def _plain_formation(space, cubes, path, s_next, here, there, direction, form, z, waiting, margins):
    """:func:`formation` as a plain check of each placement in turn, nothing kept between
    them, each margin tried in turn: the first placement that keeps the widest margin any
    keeps."""
    stations = [np.array([*here, z]), np.array([*there, z])]
    lat = form.lateral
    sides = [(lat, -lat), (-lat, lat), (0.5 * lat, -0.5 * lat), (-0.5 * lat, 0.5 * lat)]
    sides += [(a * lat, b * lat) for a, b in ((0, -1), (0, 1), (-1, 0), (1, 0), (-1.5, -0.3))]
    sides += [(a * lat, b * lat) for a, b in ((1.5, 0.3), (-0.3, -1.5), (0.3, 1.5))]
    sides += [(0.3, -0.3), (-0.3, 0.3), (0.15, -0.15), (-0.15, 0.15)]
    for k, margin in enumerate(margins):
        for gap in (form.near_gap, 0.75 * form.near_gap + 0.5, 2.0):
            for spacing in (form.spacing, 0.7 * form.spacing):
                for near_side, far_side in sides:
                    places = []
                    for ahead, side in ((gap + spacing, far_side), (gap, near_side)):
                        s = s_next + direction * ahead
                        yaw = path.heading(s) + (0.0 if direction > 0 else math.pi)
                        places.append((path.offset(s, side * direction), yaw))
                    if not _places_ok(space, [xy for xy, _ in places], stations):
                        continue
                    turned = [
                        unhidden_yaw(xy, y, cubes, stations, space.floor_z) for xy, y in places
                    ]
                    if None in turned:
                        continue
                    stops = [Stop(xy, t) for (xy, _), t in zip(places, turned, strict=True)]
                    if _formation_ok(space, stops, stations, cubes, RANGE, waiting, margin):
                        return k, stops
    return None


# (s_next, direction, where the waiting child stands off the parent, m): along the hall and
# round its turns, both ways; the first placement keeps the widest margin, a later one, a
# narrower one only, or none does.
LEGS = [
    (39.0, 1.0, (-1.25, 1.0)),
    (36.0, -1.0, (-0.82, 0.37)),
    (69.0, -1.0, (1.28, 1.4)),
    (18.0, 1.0, (-1.42, -1.13)),
    (63.0, -1.0, (0.09, 0.86)),
    (44.5, -1.0, (0.0, 0.0)),
]


@pytest.mark.parametrize(("s_next", "direction", "off"), LEGS)
def test_the_search_chooses_the_first_placement_a_plain_check_passes(hall, s_next, direction, off):
    # Places are checked once per search and reused across placements: the placement and
    # the margin kept are, to the bit, those of checking each placement in turn.
    path = RoutePath(hall.route.waypoints)
    cubes = np.asarray(hall.marker.cubes, dtype=float)
    form = hall.campaign.formation
    here = path.at(s_next - direction * 4.6)
    there = path.at(s_next)
    waiting = here + np.asarray(off)
    margins = (1.0, 0.6, 0.1)
    args = (hall.space, cubes, RANGE, path, s_next, here, there, direction, form, 0.0)
    found = formation(*args, waiting_xy=waiting, margins=margins)
    plain = _plain_formation(
        hall.space, cubes, path, s_next, here, there, direction, form, 0.0, waiting, margins
    )
    assert (found is None) == (plain is None)
    if found is not None:
        assert found[0] == plain[0]
        for got, want in zip(found[1], plain[1], strict=True):
            assert np.array_equal(got.xy, want.xy)
            assert got.yaw == want.yaw


def test_the_pair_checks_kept_between_placements_answer_as_a_plain_check(hall):
    # Every pair of a grid of stops, near the first turn where some pass and some fail for
    # each reason, checked with the kept checks and plainly, at two margins.
    path = RoutePath(hall.route.waypoints)
    cubes = np.asarray(hall.marker.cubes, dtype=float)
    z = hall.space.floor_z + float(np.mean(hall.marker.cubes, axis=0)[2])
    stations = [np.array([*path.at(36.0), z]), np.array([*path.at(40.5), z])]
    rng = np.random.default_rng(3)
    xy = path.at(41.0) + rng.uniform(-3.0, 3.0, size=(24, 2))
    stops = [Stop(p, float(y)) for p, y in zip(xy, rng.uniform(-np.pi, np.pi, 24), strict=True)]
    # The waiting child stands on the lines of sight to the first stop.
    waiting = 0.5 * (stations[0][:2] + xy[0])
    checks = FormationChecks(hall.space, cubes, stations, RANGE, waiting)
    # And each with a child just off its lines of sight from the current station, in front
    # (its crown hides a prism from an instrument at the prisms' height, or not quite), as
    # the one that moves first and second.
    pairs = [(far, near) for i, far in enumerate(stops) for near in stops[i + 1 : i + 4]]
    for stop, off in itertools.product(stops, (-0.22, 0.22)):
        v = stop.xy - stations[0][:2]
        front = Stop(
            stations[0][:2] + 0.6 * v + off * np.array([-v[1], v[0]]) / np.linalg.norm(v), stop.yaw
        )
        pairs += [(stop, front), (front, stop)]
    answers = []
    for (far, near), margin in itertools.product(pairs, (0.3, 0.1)):
        want = _formation_ok(hall.space, [far, near], stations, cubes, RANGE, waiting, margin)
        assert checks.pair_ok([far, near], margin) == want
        answers.append(want)
    assert any(answers)
    assert not all(answers)
