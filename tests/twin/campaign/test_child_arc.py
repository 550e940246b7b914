"""Where a child stands along the route: beside the way out of a dead end it is on the way
out, not on the way in past the parent."""

from __future__ import annotations

import numpy as np

from twin.campaign.paper_strategy import PaperStrategy
from twin.campaign.plan.route import RoutePath

# Into a dead end up x = 0, a turn at its end, and out again 0.6 m beside the way in.
DEAD_END = RoutePath([[0.0, -5.0], [0.0, 4.0], [-0.4, 4.0], [-0.6, 0.6], [-0.6, -5.0]])


def _strategy(path: RoutePath, arc: float) -> PaperStrategy:
    strategy = PaperStrategy()
    strategy.path, strategy._arc = path, arc
    return strategy


def test_a_child_beside_the_way_out_of_a_dead_end_is_on_the_way_out():
    # The group at the dead end's far corner (arc 9.4 m), on its way out. The child stands
    # 0.05 m from the way in (arc 5.3 m, behind the parent) and 0.65 m from the way out.
    arc = float(DEAD_END.starts[2])
    strategy = _strategy(DEAD_END, arc)
    child = np.array([0.05, 0.3])
    assert DEAD_END.project(child, near=arc) < arc
    s = strategy._child_arc(child, 1.0)
    assert s > arc
    assert np.linalg.norm(DEAD_END.at(s) - child) < 0.7
    # Going back the way it came, the way in is ahead: the nearest point.
    assert np.isclose(strategy._child_arc(child, -1.0), DEAD_END.project(child, near=arc))


def test_a_child_behind_the_group_in_a_corridor_stays_behind():
    corridor = RoutePath([[0.0, 0.0], [20.0, 0.0]])
    assert np.isclose(_strategy(corridor, 10.0)._child_arc(np.array([6.0, 0.3]), 1.0), 6.0)
    # Ahead of the group, as before.
    assert np.isclose(_strategy(corridor, 10.0)._child_arc(np.array([14.0, 0.3]), 1.0), 14.0)
