"""Station scoring from coarse to fine (a quarter of the candidates scored first, then the
neighbours of the best; the best of a smooth score is still found), and stations that
leave the children a way to the data stops."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from twin.campaign.plan.ways import WAY_CLEARANCE
from twin.planning.floor_shapes import corridor_turn
from twin.planning.stations import (
    COARSE_FROM,
    GRID,
    STATION_SLACK,
    _candidates,
    _keys,
    _scored,
    stops_reached,
)


@pytest.mark.parametrize("peak", [(3.2, -1.7), (-4.6, 5.1), (0.0, 9.5)])
def test_the_coarse_grid_and_the_best_ones_neighbours_find_a_smooth_scores_best(peak):
    centre = np.array([0.3, -0.2])
    candidates = _candidates(shapely.box(-20, -20, 20, 20), centre, GRID)
    assert len(candidates) > COARSE_FROM
    called: list[int] = []

    def score(xy):
        called.append(len(xy))
        # Visible fraction falling off from a peak off the coarse grid, in steps finer
        # than the ranking's.
        return np.clip(1.0 - 0.01 * np.linalg.norm(xy - np.asarray(peak), axis=1), 0, 1)

    fractions = _scored(candidates, centre, GRID, score)
    scored = np.isfinite(fractions)
    assert sum(called) == scored.sum() < 0.5 * len(candidates)
    every = score(candidates)
    np.testing.assert_array_equal(fractions[scored], every[scored])
    keys = _keys(candidates[scored], fractions[scored], centre)
    best_found = max(keys)
    assert best_found == max(_keys(candidates, every, centre))


def test_few_candidates_are_all_scored():
    centre = np.zeros(2)
    candidates = np.column_stack([np.arange(COARSE_FROM - 1) * GRID, np.zeros(COARSE_FROM - 1)])
    fractions = _scored(candidates, centre, GRID, lambda xy: np.full(len(xy), 0.5))
    assert np.all(fractions == 0.5)


ROOM = shapely.box(0.0, 0.0, 10.0, 6.0).union(shapely.box(4.4, 5.9, 5.6, 12.0)).buffer(-0.3)
"""Where a child's centre may be: a 10 x 6 m room with a 1.2 m passage going on north
from the middle of its north wall, shrunk by the child's clearance."""

IN_PASSAGE = np.column_stack([np.full(4, 5.0), np.linspace(8.0, 11.0, 4)])
IN_ROOM = np.array([[2.0, 2.0], [8.0, 2.0], [3.0, 4.5], [7.0, 4.5]])


@pytest.mark.parametrize(
    ("station", "stops", "reached"),
    [
        # The parent in the passage's mouth: the children, arriving in the room, cannot
        # pass it into the passage.
        ((5.0, 5.6), IN_PASSAGE, False),
        # The same parent does not keep them from the room's stops.
        ((5.0, 5.6), IN_ROOM, True),
        # Nor from the passage's stops when they are mostly in the room.
        ((5.0, 5.6), np.vstack([IN_ROOM, IN_PASSAGE[:1]]), True),
        # A parent in the room, clear of the mouth, leaves the passage open.
        ((5.0, 2.5), IN_PASSAGE, True),
        # A parent in the passage: the children may arrive from behind it as well.
        ((5.0, 7.0), IN_PASSAGE[1:], False),
    ],
)
def test_a_parent_in_a_passages_mouth_cuts_the_children_off_the_stops_beyond(
    station, stops, reached
):
    assert stops_reached(ROOM, np.array(station), stops) is reached


HAIRPIN = corridor_turn(2.4, 180).buffer(-WAY_CLEARANCE)
"""Where a child's centre may be in a 2.4 m corridor that turns back on itself (its first
leg along +x, centred on y = 0)."""

BEHIND = np.column_stack([np.linspace(0.5, 2.5, 5), np.linspace(-0.6, 0.6, 5)])
"""Data stops in the first leg, behind a parent standing at x = 4 m."""


@pytest.mark.parametrize("across", [0.0, 0.04, -0.04])
def test_a_parent_near_a_corridors_middle_closes_it_to_the_children(across):
    # Beside a parent on the middle line, 2.4 m of corridor leave a child a few centimetres
    # of way: the parent arriving that far off its station closes it.
    assert STATION_SLACK > 0.04
    assert not stops_reached(HAIRPIN, np.array([4.0, across]), BEHIND)


@pytest.mark.parametrize("across", [-0.6, 0.6])
def test_a_parent_beside_a_corridors_wall_leaves_the_children_a_way(across):
    assert stops_reached(HAIRPIN, np.array([4.0, across]), BEHIND)


CORRIDOR = corridor_turn(2.0, 45).buffer(-WAY_CLEARANCE)
"""Where a child's centre may be in a 2 m corridor along +x that turns 45 degrees at
x = 12 m: a parent anywhere in it closes it."""

NEARER = np.column_stack([np.linspace(1.0, 2.8, 4), np.linspace(-0.5, 0.5, 4)])
FARTHER = np.column_stack([np.linspace(5.2, 8.0, 4), np.linspace(-0.5, 0.5, 4)])
"""Data stops in the corridor before and beyond a parent standing at x = 4 m."""


@pytest.mark.parametrize(
    ("start", "stops", "reached"),
    [
        # The group comes from the corridor's end: the children, ahead of the parent,
        # stand beyond it, with the stops there and not with those behind it.
        ((-0.5, 0.0), FARTHER, True),
        ((-0.5, 0.0), NEARER, False),
        # Most of them beyond it: those do.
        ((-0.5, 0.0), np.vstack([FARTHER, FARTHER + 0.2, NEARER[-1:]]), True),
        # From beyond the turn the other way round, though the start is far from the
        # station.
        ((16.0, 4.0), NEARER, True),
        ((16.0, 4.0), FARTHER, False),
    ],
)
def test_a_parent_closing_a_corridor_leaves_the_children_the_stops_away_from_the_start(
    start, stops, reached
):
    assert stops_reached(CORRIDOR, np.array([4.0, 0.0]), stops, np.array(start)) is reached


@pytest.mark.parametrize("stops", [NEARER, FARTHER])
def test_without_a_start_the_children_may_arrive_on_either_side_of_a_closed_corridor(stops):
    # The two sides share the circle where the children may arrive.
    assert not stops_reached(CORRIDOR, np.array([4.0, 0.0]), stops)
