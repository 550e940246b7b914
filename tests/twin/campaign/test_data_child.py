"""The child that takes a camera's data: the other one takes it where the first has no way
to the stops past it (it stands in a doorway's way)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np

from twin.campaign.paper_strategy import PaperStrategy, _no_way
from twin.campaign.strategy import Stop, StopPlan
from twin.scenario import load_scenario
from twin.scenario.schema import Obstacle

ROOT = Path(__file__).resolve().parents[3]
SMOKE = load_scenario(ROOT / "scenarios" / "smoke.toml")  # x -2..8, y -3..3
# A wall across the room at x = 3 m with a 1.2 m door (y -0.6..0.6): the parent stands in
# the room beyond it, where the camera's stops are.
WALL = (
    Obstacle(name="wall_south", center=(3.0, -1.8), size=(0.2, 2.4, 2.5)),
    Obstacle(name="wall_north", center=(3.0, 1.8), size=(0.2, 2.4, 2.5)),
)
SPACE = SMOKE.space.model_copy(update={"obstacles": WALL})
STOPS = [Stop(np.array([5.0, -1.0]), 0.0), Stop(np.array([5.5, 0.8]), 0.0)]


class _Stops(PaperStrategy):
    """The paper's choice of child, with fixed stops."""

    def _stops_for(self, view, child, anchor, cam, points):
        return StopPlan(child, STOPS)


def _view(near_door: str, far: str, anchor_xy):
    poses = {
        "parent": np.array([6.5, 1.5, 0.0]),
        near_door: np.array([*anchor_xy, 0.0]),
        far: np.array([0.0, -0.3, 0.0]),
    }
    return SimpleNamespace(
        scenario=SMOKE.model_copy(update={"space": SPACE}),
        parent=SimpleNamespace(translation=np.array([6.5, 1.5, 0.5])),
        children=("child1", "child2"),
        robot_pose=lambda robot: poses[robot],
    )


def _taker(view) -> str:
    return _Stops().data_stops(view, SMOKE.cameras[0].name, "visit", 20).child


def test_a_child_standing_in_the_doorway_takes_the_data_the_other_has_no_way_to():
    # The camera's view is nearer child1 (the paper's choice), but child2 stands 0.6 m in
    # front of the door: child1 cannot pass it, child2 can go through.
    view = _view("child2", "child1", [2.3, 0.0])
    plan = StopPlan("child1", STOPS)
    assert _no_way(view, "child1", "child2", plan)
    assert not _no_way(view, "child2", "child1", plan)
    assert _taker(view) == "child2"


def test_the_paper_child_takes_the_data_where_it_has_a_way():
    # child2 stands aside, against the wall north of the door: child1 passes it.
    view = _view("child2", "child1", [2.3, 2.3])
    assert not _no_way(view, "child1", "child2", StopPlan("child1", STOPS))
    assert _taker(view) == "child1"
