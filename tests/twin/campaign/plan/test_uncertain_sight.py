"""Lines of sight planned for the group's position uncertainty: after a long travel the
group truly stands off where CPS believes it by about the parent's position error, and a
formation planned to graze a corner would hide a prism."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

from twin.campaign.paper_strategy import PaperStrategy
from twin.campaign.plan.clearance import body_points, sight_clear
from twin.campaign.plan.formation import (
    SIGHT_MARGIN,
    UNCERTAINTY_SIGMAS,
    formation,
    sight_margins,
)
from twin.campaign.plan.legs import leg_goals
from twin.campaign.plan.route import RoutePath
from twin.campaign.records import CalibrationRecord
from twin.campaign.strategy import CampaignView, Leg, Visit
from twin.instruments.total_station import TotalStationSpec
from twin.localization.pose import ParentPose
from twin.scenario import scenario_from_dict
from twin.scenario.schema import Scenario

CORRIDOR = Path(__file__).resolve().parents[4] / "scenarios" / "corridor.toml"
RANGE = (1.3, 2200.0)
"""The instrument's range (Table I), m."""

S_BEFORE_CORNER = 13.75
"""Where the parent stands, m of route: the travel's first leg ends past the corner, where
the children have room with the nominal margin only."""


@pytest.fixture(scope="module")
def corner() -> Scenario:
    """The corridor (3 m wide) turned into an L: east 20 m, then north 16 m."""
    data = tomllib.loads(CORRIDOR.read_text())
    data["space"].update(size=[26.0, 20.0, 3.0], origin=[-3.0, -1.5], floor_patches=[])
    data["space"]["obstacles"] = [
        {"name": "inside_of_the_l", "center": [7.75, 9.75], "size": [21.5, 16.5, 3.0]}
    ]
    data["route"]["waypoints"] = [[0.0, 0.0], [20.0, 0.0], [20.0, 16.0]]
    # One camera near the corner, looking up the north leg.
    data["cameras"] = [{**data["cameras"][0], "position": [21.2, 3.0, 2.0]}]
    data["cameras"][0]["view_direction"] = [-0.05, 0.9, -0.42]
    data["calibration"]["visits"] = [{"camera": "cam1", "station": [20.0, 14.0]}]
    return scenario_from_dict(data)


def test_the_margin_grows_with_the_parents_uncertainty():
    assert sight_margins(0.0) == (SIGHT_MARGIN,)
    assert sight_margins(0.9 * SIGHT_MARGIN / UNCERTAINTY_SIGMAS) == (SIGHT_MARGIN,)
    # Two sigmas where they are more than the nominal margin; one sigma too where it is.
    assert sight_margins(0.08) == pytest.approx((UNCERTAINTY_SIGMAS * 0.08, SIGHT_MARGIN))
    assert sight_margins(0.15) == pytest.approx((UNCERTAINTY_SIGMAS * 0.15, 0.15, SIGHT_MARGIN))


def _clear_by(sc: Scenario, stops, stations, margin: float) -> bool:
    """Whether every prism is in sight of both stations by ``margin``, m."""
    cubes = np.asarray(sc.marker.cubes, dtype=float)
    floor = sc.space.floor_z
    return all(
        sight_clear(sc.space, inst, body_points(stop.xy, stop.yaw, cubes, floor)[0], margin).all()
        for stop in stops
        for inst in stations
    )


@pytest.mark.parametrize("margin", [SIGHT_MARGIN, 0.25, 0.4])
def test_a_formation_keeps_its_lines_of_sight_clear_by_its_margin(corner, margin):
    path = RoutePath(corner.route.waypoints)
    cubes = np.asarray(corner.marker.cubes, dtype=float)
    form = corner.campaign.formation
    found = 0
    for s in np.arange(10.0, 24.0, 1.0):
        for length in (form.step, 0.5 * form.step):
            here, there = path.at(s), path.at(s + length)
            kept = formation(
                corner.space, cubes, RANGE, path, s + length, here, there, 1.0, form, 0.0,
                margins=(margin,),
            )  # fmt: skip
            if kept is None:
                continue
            stops = kept[1]
            found += 1
            stations = [np.array([*here, 0.0]), np.array([*there, 0.0])]
            assert _clear_by(corner, stops, stations, margin)
    assert found >= 15  # of 28 legs: the test is not vacuous


class _View(CampaignView):
    """The campaign's knowledge at a leg: the parent where the test puts it, with the
    position standard deviation it gives, the children behind it on the route."""

    def __init__(self, scenario: Scenario, s: float, std: float) -> None:
        self._scenario = scenario
        path = RoutePath(scenario.route.waypoints)
        xy = path.at(s)
        cov = np.diag([1e-8, std**2, std**2, 1e-8])
        self._parent = ParentPose(0.0, np.array([xy[0], xy[1], 0.0]), cov)
        self._poses = {
            "parent": np.array([xy[0], xy[1], 0.0]),
            "child1": np.array([*path.at(s - 2.0), 0.0]),
            "child2": np.array([*path.at(s - 3.5), 0.0]),
        }

    @property
    def scenario(self) -> Scenario:
        return self._scenario

    @property
    def instrument(self) -> TotalStationSpec:
        return TotalStationSpec()

    @property
    def parent_name(self) -> str:
        return "parent"

    @property
    def children(self) -> tuple[str, ...]:
        return ("child1", "child2")

    @property
    def led_count(self) -> int:
        return 4

    @property
    def parent(self) -> ParentPose:
        return self._parent

    def child_position(self, child: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return self._poses[child].copy(), np.eye(3) * 1e-6

    def robot_pose(self, robot: str) -> NDArray[np.float64]:
        return self._poses[robot].copy()

    @property
    def calibrations(self) -> tuple[CalibrationRecord, ...]:
        return ()


def _first_leg(scenario: Scenario, std: float) -> Leg:
    view = _View(scenario, S_BEFORE_CORNER, std)
    strategy = PaperStrategy()
    strategy.start(view)
    visit = scenario.calibration.visits[0]
    leg = strategy.next_leg(view, Visit("cam1", 1, np.asarray(visit.station, dtype=float), 0.0))
    assert isinstance(leg, Leg)
    return leg


def _full_leg_end(scenario: Scenario) -> float:
    """Where the travel's first leg ends when nothing shortens it, m of route."""
    path = RoutePath(scenario.route.waypoints)
    goal = path.project(scenario.calibration.visits[0].station)
    return leg_goals(path, S_BEFORE_CORNER, goal, scenario.campaign.formation.step)[0]


def test_a_certain_group_turns_the_corner_in_a_full_leg(corner):
    leg = _first_leg(corner, std=0.005)
    path = RoutePath(corner.route.waypoints)
    assert path.project(leg.parent.stop.xy) == pytest.approx(_full_leg_end(corner))


def test_an_uncertain_group_turns_the_corner_in_shorter_legs_clear_by_its_uncertainty(corner):
    std = 0.2
    path = RoutePath(corner.route.waypoints)
    here, s_full = path.at(S_BEFORE_CORNER), _full_leg_end(corner)
    cubes = np.asarray(corner.marker.cubes, dtype=float)
    form = corner.campaign.formation
    margin = UNCERTAINTY_SIGMAS * std
    full = formation(
        corner.space, cubes, RANGE, path, s_full, here, path.at(s_full), 1.0, form, 0.0,
        margins=(margin,),
    )  # fmt: skip
    assert full is None  # the full leg has no room for the margin: the case is the one meant
    leg = _first_leg(corner, std)
    s_next = path.project(leg.parent.stop.xy)
    assert S_BEFORE_CORNER < s_next < s_full - 1.0
    stations = [np.array([*here, 0.0]), np.array([*leg.parent.stop.xy, 0.0])]
    stops = [move.stop for move in leg.children]
    assert _clear_by(corner, stops, stations, margin)


def test_where_nothing_clears_the_uncertainty_the_nominal_margin_still_serves(corner):
    # So uncertain that no leg has room for its margin: the full leg, as with no doubt.
    leg = _first_leg(corner, std=2.0)
    path = RoutePath(corner.route.waypoints)
    assert path.project(leg.parent.stop.xy) == pytest.approx(_full_leg_end(corner))


def test_one_pass_over_the_placements_is_trying_each_margin_in_turn(corner):
    path = RoutePath(corner.route.waypoints)
    cubes = np.asarray(corner.marker.cubes, dtype=float)
    form = corner.campaign.formation
    tries = sight_margins(0.2)
    kept = set()
    for s in np.arange(8.0, 26.0, 0.5):
        for length in (form.step, 0.5 * form.step, 0.25 * form.step):
            args = (corner.space, cubes, RANGE, path, s + length, path.at(s))
            args += (path.at(s + length), 1.0, form, 0.0)
            one_pass = formation(*args, None, tries)
            in_turn = None
            for k, margin in enumerate(tries):
                alone = formation(*args, None, (margin,))
                if alone is not None:
                    in_turn = (k, alone[1])
                    break
            if in_turn is None:
                assert one_pass is None
                continue
            assert one_pass is not None
            assert one_pass[0] == in_turn[0]
            kept.add(in_turn[0])
            for a, b in zip(one_pass[1], in_turn[1], strict=True):
                assert np.array_equal(a.xy, b.xy)
                assert a.yaw == b.yaw
    assert kept == {0, 1, 2}  # each margin is the one kept somewhere
