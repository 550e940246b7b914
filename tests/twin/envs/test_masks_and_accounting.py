"""The environment's bookkeeping, value by value: the fallback's order, the moves allowed
between travels (the budget, the station the group stands at, the start), the end-only
mask where no formation fits, the time a move costs and the reward's time term."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import twin.sim  # noqa: F401  (headless rendering)
from twin.batch.estimators import ParentEstimates
from twin.batch.execute import transfer_rms
from twin.batch.steps import Drive
from twin.envs import CpsCampaignEnv
from twin.envs.episode import visit_mask
from twin.envs.leg_choices import LegChoices
from twin.envs.moves import MoveLayout
from twin.envs.planner import CampaignPlanner
from twin.envs.site_stations import START
from twin.envs.stands import StandPlanner
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"
PLANNERS = ("campaign", "stands")

# MoveLayout(max_stations=3): legs 0..11 (formation f, step s at 3 f + s; steps 0.5, 1,
# 1.5), calibrate 12, go_to(0..2) 13..15, return_start 16, end 17.
LAYOUT = MoveLayout(max_stations=3)


def _mask(*allowed: int) -> np.ndarray:
    mask = np.zeros(LAYOUT.size, dtype=bool)
    mask[list(allowed)] = True
    return mask


def test_the_layout_numbers_its_moves_as_documented():
    assert (LAYOUT.legs, LAYOUT.calibrate, LAYOUT.return_start, LAYOUT.end) == (12, 12, 16, 17)
    assert [LAYOUT.go_to(k) for k in range(3)] == [13, 14, 15]
    assert LAYOUT.size == 18
    assert LAYOUT.leg_of(4) == ("side_by_side", 1.0)
    assert LAYOUT.leg("long", 0.5) == 9


@pytest.mark.parametrize(
    ("action", "allowed", "taken", "why"),
    [
        (4, (3, 5), 3, "same formation, equal distance: the shorter step"),
        (3, (4, 5), 4, "same formation: the nearest step"),
        (3, (5,), 5, "same formation: a longer step before another formation"),
        (5, (0, 1, 4), 4, "same formation: the nearest step, not the nearest value"),
        (4, (2, 7), 2, "other formations in the layout's order"),
        (10, (1, 2, 8), 1, "another formation: its step nearest the asked one, shorter first"),
        (10, (0, 2, 8), 0, "another formation: at equal distance the shorter step"),
        (4, (14, 13, 17), 13, "no leg allowed: go_to in station order"),
        (4, (16, 17), 16, "no leg allowed: return_start before end"),
        (12, (13, 17), 13, "calibrate refused: the first go_to"),
        (16, (12, 17), 12, "return_start refused: calibrate first"),
        (13, (17,), 17, "only end"),
        (14, (7, 2), 2, "a move between travels where only legs are allowed: the first leg"),
    ],
)
def test_the_fallback_takes_the_nearest_allowed_move_in_the_documented_order(
    action, allowed, taken, why
):
    assert LAYOUT.fallback(action, _mask(*allowed)) == taken, why


@pytest.mark.parametrize("action", [-1, LAYOUT.size])
def test_an_action_outside_the_space_has_no_fallback(action):
    with pytest.raises(ValueError, match=f"action {action} is outside the action space"):
        LAYOUT.fallback(action, _mask(14, 15, 16))


def test_the_moves_between_travels_are_the_budgets_and_the_places():
    # Stations a, b, c in go_to order; the group stands at b. Route distances 5, 0, 10 m,
    # 7 m back to the start; 7 m of budget left.
    order = ("a", "b", "c")
    distances = {"a": 5.0, "b": 0.0, "c": 10.0, START: 7.0}
    mask = np.ones(LAYOUT.size, dtype=bool)  # every entry must be set
    visit_mask(mask, LAYOUT, order, "b", True, distances.__getitem__, 7.0)
    assert np.flatnonzero(mask).tolist() == [
        LAYOUT.calibrate,
        LAYOUT.go_to(0),  # 5 m <= 7 m
        LAYOUT.return_start,  # 7 m <= 7 m: a travel that uses the budget up is allowed
        LAYOUT.end,
    ]  # not go_to(1), where the group stands; not go_to(2), 10 m > 7 m
    visit_mask(mask, LAYOUT, order, "b", False, distances.__getitem__, 6.999)
    assert np.flatnonzero(mask).tolist() == [LAYOUT.go_to(0), LAYOUT.end]
    # At the start: no return to it; every station by its distance.
    at_start = {"a": 3.0, "b": 4.0, "c": 4.001, START: 0.0}
    visit_mask(mask, LAYOUT, order, START, False, at_start.__getitem__, 4.0)
    assert np.flatnonzero(mask).tolist() == [LAYOUT.go_to(0), LAYOUT.go_to(1), LAYOUT.end]
    # Between stations (here None): every station and the start by distance.
    visit_mask(mask, LAYOUT, order, None, False, distances.__getitem__, 100.0)
    assert np.flatnonzero(mask).tolist() == [13, 14, 15, 16, 17]


def _to_station(env: CpsCampaignEnv) -> dict:
    """From the start, travel to the smoke room's station by its first allowed legs; the
    info on arrival."""
    _, info = env.reset(seed=5)
    assert info["decision"] == "visit"
    _, _, _, _, info = env.step(env.layout.go_to(0))
    while info["decision"] == "leg":
        _, _, _, _, info = env.step(int(np.flatnonzero(info["action_mask"])[0]))
    return info


@pytest.mark.parametrize("planner", PLANNERS)
def test_the_budget_left_after_a_travel_decides_the_return(planner):
    # The smoke room's station is 0.5 m along the route from the start: the way there and
    # back is 1.0 m. With 0.95 m of budget the group may go, not come back; with 1.05 m
    # it may; with 0.45 m it may not even go.
    layout = MoveLayout()
    allowed = {}
    for budget in (0.95, 1.05):
        env = CpsCampaignEnv(SMOKE, planner=planner, strict=True, budget_m=budget)
        _, info = env.reset(seed=5)
        assert info["action_mask"][layout.go_to(0)], budget
        assert not info["action_mask"][layout.return_start], "at the start already"
        info = _to_station(env)
        assert env.planner.here() == "cam1@1"
        assert env.planner.travelled == pytest.approx(0.5, abs=1e-6)
        assert env.planner.route_distance(env.planner.stations[START]) == pytest.approx(0.5)
        # The group stands at the only station: no travel to it.
        assert not info["action_mask"][layout.go_to(0)]
        assert info["action_mask"][layout.calibrate]
        assert info["action_mask"][layout.end]
        allowed[budget] = bool(info["action_mask"][layout.return_start])
        env.close()
    assert allowed == {0.95: False, 1.05: True}
    env = CpsCampaignEnv(SMOKE, planner=planner, strict=True, budget_m=0.45)
    _, info = env.reset(seed=5)
    assert np.flatnonzero(info["action_mask"]).tolist() == [layout.end]
    env.close()


def _no_room(planner: str, monkeypatch: pytest.MonkeyPatch):
    """A planner of the smoke room whose legs never find room for a formation."""
    scenario, layout = load_scenario(SMOKE), MoveLayout()
    if planner == "stands":
        found = StandPlanner(scenario, layout, 10.0)
        monkeypatch.setattr(found.site, "leg", lambda *args, **kwargs: None)
        return found
    monkeypatch.setattr(
        LegChoices, "options", lambda self, view, goal, layout: [None] * layout.legs
    )
    found = CampaignPlanner(scenario, layout, 10.0, memo=False)
    found.take_pending()
    return found


@pytest.mark.parametrize("planner", PLANNERS)
def test_where_no_formation_has_room_end_is_the_only_move(planner, monkeypatch):
    layout = MoveLayout()
    # With room, a leg decision allows legs and never ``end``.
    scenario = load_scenario(SMOKE)
    normal = (
        StandPlanner(scenario, layout, 10.0)
        if planner == "stands"
        else CampaignPlanner(scenario, layout, 10.0, memo=False)
    )
    normal.act(layout.go_to(0))
    assert normal.decision == "leg"
    assert normal.mask[: layout.legs].any()
    assert not normal.mask[layout.legs :].any()
    normal.close()
    stuck = _no_room(planner, monkeypatch)
    stuck.act(layout.go_to(0))
    assert stuck.decision == "leg"
    assert np.flatnonzero(stuck.mask).tolist() == [layout.end]
    stuck.act(layout.end)
    assert stuck.done
    stuck.close()


@pytest.mark.parametrize("planner", PLANNERS)
def test_the_reward_charges_each_moves_own_time(planner):
    # The same episode with and without a cost of time: each step's rewards differ by the
    # cost times the time that move took (info["time_s"], from the reset's on), no more.
    cost = 0.7
    rewards, times = {}, {}
    for per_s in (0.0, cost):
        env = CpsCampaignEnv(SMOKE, planner=planner, cost_per_s=per_s)
        _, info = env.reset(seed=2)
        clock, got = [info["time_s"]], []
        layout = env.layout
        for action in (layout.go_to(0), None, layout.calibrate, layout.return_start, None):
            if action is None:
                action = int(np.flatnonzero(info["action_mask"])[0])
            _, reward, _, _, info = env.step(action)
            got.append(reward)
            clock.append(info["time_s"])
        rewards[per_s], times[per_s] = np.array(got), np.diff(clock)
        env.close()
    np.testing.assert_array_equal(times[0.0], times[cost])
    assert (times[cost][[1, 2]] > 1.0).all(), "a leg and a data set take time"
    assert times[cost][0] == 0.0, "choosing the station takes none"
    np.testing.assert_allclose(rewards[0.0] - rewards[cost], cost * times[cost], atol=1e-9)


def test_the_tables_clock_counts_each_robots_drive_and_the_shots():
    # The stands planner's time: a leg costs each robot's straight drive at its top speed
    # from where it stood, plus the shots' time measured on the paper's run; a station's
    # data set and calibration the time they took in that run; choosing a station nothing.
    planner = StandPlanner(load_scenario(SMOKE), MoveLayout(), 10.0)
    site, layout = planner.site, planner.layout
    # The robots stand where the start's reference data left them.
    where = {name: xy.copy() for name, xy in site.start_xy.items()}
    for step in site.start:
        if isinstance(step, Drive):
            where[step.robot] = step.believed[:2].copy()
    assert planner.time == site.start_time
    # The shots of a leg take a fraction of a second (three shots a placed child).
    assert 0.05 < site.leg_overhead < 2.0
    moves = (layout.go_to(0), None, layout.calibrate, layout.return_start)
    for action in moves:
        before = planner.time
        if action is None:
            action = int(np.flatnonzero(planner.mask)[0])
            leg = planner._legs[action]
            drives = sum(
                float(np.linalg.norm(xy - where[robot])) / site.speed[robot]
                for robot, xy in leg.stops.items()
            )
            assert drives > 0.0
            expected = drives + site.leg_overhead
            where.update(leg.stops)
        elif action == layout.calibrate:
            data = site.data[planner.here()]
            expected = data.time
            assert expected > 1.0
            where.update(data.stops)
        else:
            expected = 0.0
        planner.act(action)
        assert planner.time - before == pytest.approx(expected, rel=1e-12, abs=1e-12)
    planner.close()


def test_the_transfer_error_is_the_parents_pose_error_carried_to_the_camera():
    # A camera 3 m east and 4 m north of the instrument: the parent's yaw error d moves it
    # by d (-4, 3, 0), its position error by itself. With var(yaw) = a, var(x, y, z) =
    # b, c, e and cov(yaw, x) = p, cov(yaw, y) = q: E|move|^2 = 25 a + b + c + e - 8 p + 6 q.
    a, b, c, e, p, q = 1e-6, 4e-6, 9e-6, 1e-6, 1.5e-6, -1e-6
    cov = np.array([[a, p, q, 0.0], [p, b, 0.0, 0.0], [q, 0.0, c, 0.0], [0.0, 0.0, 0.0, e]])
    parent = ParentEstimates(np.array([0.7]), np.array([[1.0, 2.0, 0.5]]), cov[None])
    got = transfer_rms(parent, np.array([[4.0, 6.0, 0.5]]))
    assert got[0] ** 2 == pytest.approx(25 * a + b + c + e - 8 * p + 6 * q, rel=1e-12)
