"""The route as a path walked by arc length: projection onto it, near its ends and where it
comes back past itself."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from twin.campaign.plan.route import RoutePath

# The closed hall's route: out along y = 0, back along y = 4, and down to the start.
CLOSED = RoutePath([[0.0, 0.0], [40.0, 0.0], [40.0, 4.0], [-5.0, 4.0], [-5.0, 0.0], [0.0, 0.0]])


def test_a_point_past_the_end_of_a_closed_route_projects_to_its_end():
    # A child's stop ahead of the last station lies past the route's end (x > 0), next to
    # the route's first metres. Searching near the end (arc 93.7 of 98), the part of the
    # route 4.7 m away along y = 4 is nearer than the end itself (5.05 m), but the route's
    # straight continuation past its end is 0.7 m away: the stop is past the end. Its
    # projection used to be 79 m, and the child drove back round the corner through the
    # parked parent.
    assert CLOSED.length == 98.0
    assert CLOSED.project([5.0, -0.7], near=93.74) == 98.0
    assert CLOSED.project([-1.0, 0.5], near=93.74) == 97.0  # on the route: as before
    # Searching near the start, the same point is on the route's first segment.
    assert CLOSED.project([5.0, -0.7], near=2.0) == 5.0


@given(st.floats(0.01, 10.0), st.floats(-3.0, 3.0), st.sampled_from([None, 2.0, 9.0, 15.0]))
def test_on_an_open_route_points_past_an_end_project_to_it(beyond, side, near):
    path = RoutePath([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    assert path.project([-beyond, side], near) == 0.0
    assert path.project([10.0 + side, 10.0 + beyond], near) == 20.0
    # A point beside the route still projects onto it.
    assert np.isclose(path.project([10.0 + 0.5 * side, 5.0], near), 15.0)


def test_on_a_route_back_along_itself_the_pass_nearest_in_arc_length_is_taken():
    # Out to x = 4 m and back along the same line: every point of it is on both passes.
    # The group's place after a leg that ended at arc length 4.245 m (x = 3.755 m, on the
    # way back) is on the way back, not the way out; without ``near``, the first pass.
    path = RoutePath([[0.0, 0.0], [4.0, 0.0], [0.0, 0.0]])
    assert np.isclose(path.project([3.78, 0.02], near=4.245), 4.22)
    assert np.isclose(path.project([3.78, -0.02], near=3.0), 3.78)
    assert np.isclose(path.project([3.78, 0.02]), 3.78)
    assert np.isclose(path.project([2.0, 0.01], near=7.9), 6.0)


def test_a_point_on_the_continuation_far_past_the_end_is_not_near_a_group_at_the_start():
    # The route turns back and its last leg (-6, -3) -> (-2, -1), 21.5 m on, points at the
    # route's first metres: (2, 1) is on its straight continuation, 4.5 m past the end, and
    # 1 m beside the first segment. A group 2 m along the route (window 20 m) is at the
    # first segment; the end's continuation lies 26 m along, outside the window. Taking it
    # sent a child standing there back along the whole route, through a doorway's wall.
    path = RoutePath([[0.0, 0.0], [4.0, 0.0], [4.0, -3.0], [-6.0, -3.0], [-2.0, -1.0]])
    assert np.isclose(path.project([2.0, 1.0], near=2.0), 2.0)
    # Searching near the end, the same point is past the end.
    assert np.isclose(path.project([2.0, 1.0], near=20.0), path.length)
    assert np.isclose(path.project([2.0, 1.0]), path.length)
