"""The campaign asks, its strategy decides: the questions come one at a time and can be
answered from outside; a strategy's visits, returns and refusals are executed as given;
the campaign's own recoveries are events, not failures."""

from __future__ import annotations

import math
import typing
from pathlib import Path

import numpy as np
import pytest

import twin.sim  # noqa: F401  (headless rendering is configured before MuJoCo loads)
from twin.campaign import Campaign, PaperStrategy, strategy_named
from twin.campaign.strategies import STRATEGIES, strategy_for, strategy_name
from twin.campaign.strategy import (
    DataStops,
    NextLeg,
    NextVisit,
    NoLeg,
    PlannedStop,
    ReferenceCameras,
    Return,
    Stop,
    StopPlan,
    Visit,
)
from twin.hal.wrappers import MobileBaseWrapper, TotalStationWrapper, wrapped
from twin.instruments.errors import NoPrismInConeError
from twin.run.runner import run_scenario
from twin.scenario import load_scenario
from twin.scenario.schema import StrategyName
from twin.sim.rig import build_sim_rig
from twin.sim.world import build_world

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"
HALL = ROOT / "scenarios" / "paper_hall.toml"


class Records:
    """A recorder that keeps every record, by topic."""

    def __init__(self) -> None:
        self.by_topic: dict[str, list] = {}

    def record(self, topic: str, record: object, timestamp: float) -> None:
        self.by_topic.setdefault(topic, []).append(record)


def _campaign(strategy=None, scenario=SMOKE):
    sc = load_scenario(scenario)
    sim = build_sim_rig(build_world(sc), "geometric")
    records = Records()
    return Campaign(sim.rig, sc, records, strategy=strategy), sim, records


# -- the questions -------------------------------------------------------------------------------
def test_answering_the_questions_one_by_one_is_running_the_campaign():
    ran, sim_a, _ = _campaign(PaperStrategy())
    outcome = ran.run()
    sim_a.close()

    stepped, sim_b, _ = _campaign()
    strategy = PaperStrategy()
    strategy.start(stepped.view)
    steps = stepped.steps()
    asked = []
    answer = None
    try:
        while True:
            question = steps.send(answer)
            asked.append(type(question).__name__)
            answer = question.ask(strategy, stepped.view)
    except StopIteration as end:
        stepped_outcome = end.value
    sim_b.close()
    # The smoke room: a reference set of cam1, then one visit one leg away.
    assert asked == [
        "ReferenceCameras",
        "DataStops",
        "NextVisit",
        "NextLeg",
        "NextLeg",
        "DataStops",
        "NextVisit",
    ]
    (a,), (b,) = outcome.calibrations, stepped_outcome.calibrations
    assert a.parameters == b.parameters


def test_an_answer_from_outside_is_what_the_campaign_does():
    campaign, sim, records = _campaign()
    paper = PaperStrategy()
    paper.start(campaign.view)
    steps = campaign.steps()
    answer = None
    try:
        while True:
            question = steps.send(answer)
            if isinstance(question, ReferenceCameras):
                answer = []  # no reference data set
            else:
                answer = question.ask(paper, campaign.view)
    except StopIteration:
        pass
    sim.close()
    datasets = [(d.dataset, d.camera) for d in records.by_topic["/campaign/dataset"]]
    assert datasets == [("visit", "cam1")]
    assert len(campaign.outcome.calibrations) == 1


class _Scripted(PaperStrategy):
    """The paper's legs and data stops, towards goals given in advance."""

    def __init__(self, goals) -> None:
        self.goals = list(goals)

    def reference_cameras(self, view):
        return []

    def next_visit(self, view):
        return self.goals.pop(0) if self.goals else None


def test_a_return_is_travelled_without_calibrating(tmp_path):
    cam1 = np.array([1.0, 0.0])
    goals = [
        Visit("cam1", 1, cam1, 0.0),
        Return(np.array([12.5, 0.0]), 0.0, "out to camera 2's station and back"),
        Visit("cam1", 2, cam1, math.pi),
    ]
    campaign, sim, records = _campaign(_Scripted(goals), HALL)
    outcome = campaign.run()
    true_parent = sim.world.instrument_pose(sim.rig.parent.name)[0]
    position = sim.frame.points(true_parent)
    sim.close()
    assert [(c.camera, c.visit) for c in outcome.calibrations] == [("cam1", 1), ("cam1", 2)]
    stages = [s.stage for s in records.by_topic["/campaign/stage"]]
    assert stages.count("return") == 1
    assert stages.count("station") == 2
    fixes = records.by_topic["/campaign/parent_fix"]
    # Out 11.5 m and back: the parent's track passed camera 2's station.
    assert max(f.translation[0] for f in fixes) == pytest.approx(12.5, abs=0.1)
    assert outcome.travelled == pytest.approx(1.0 + 2 * 11.5, abs=1.0)
    assert np.linalg.norm(position[:2] - cam1) < 0.1
    assert outcome.calibrations[1].distance_travelled == pytest.approx(24.0, abs=1.0)


class _NoRoom(PaperStrategy):
    def next_leg(self, view, goal):
        return NoLeg("no_formation", "no place for the children (test)", "nowhere to go")


def test_no_leg_ends_the_campaign_and_says_why():
    campaign, sim, _ = _campaign(_NoRoom())
    outcome = campaign.run()
    sim.close()
    assert outcome.calibrations == []
    assert outcome.failures["no_formation"] == 1
    assert outcome.failures["campaign_aborted"] == 1
    (skipped,) = outcome.skipped
    assert (skipped.camera, skipped.reason, skipped.message) == (
        "cam1",
        "campaign_aborted",
        "nowhere to go",
    )


def test_a_plan_replaces_each_failed_stop_with_the_next_spare():
    stops = [Stop(np.array([float(k), 0.0]), 0.0) for k in range(5)]
    plan = StopPlan("child1", stops[:2], stops[2:], heading=lambda s: None if s.xy[0] == 1 else 0.5)
    first = plan.next()
    assert first == PlannedStop(stops[0], 0.5)
    second = plan.next()
    assert second is not None
    assert second.yaw is None  # no heading shows the prisms
    plan.replace()
    plan.replace()
    assert [plan.next().stop.xy[0] for _ in range(2)] == [2.0, 3.0]
    assert plan.next() is None
    assert not plan.empty  # a spare is left
    assert StopPlan("child1", []).empty


def test_strategies_are_known_by_name():
    assert isinstance(strategy_named("paper"), PaperStrategy)
    with pytest.raises(ValueError, match=r"unknown strategy 'bold'; strategies: paper"):
        strategy_named("bold")
    sc = load_scenario(SMOKE)
    bad = sc.model_copy(
        update={"campaign": sc.campaign.model_copy(update={"strategy": "bold"}), "source": "x.toml"}
    )
    with pytest.raises(ValueError, match=r"campaign\.strategy in x\.toml: unknown strategy"):
        strategy_for(bad)
    with pytest.raises(ValueError, match=r"--strategy: unknown strategy 'bolder'"):
        strategy_for(sc, "bolder")


def test_the_registry_makes_every_name_a_scenario_accepts():
    assert set(STRATEGIES) == set(typing.get_args(StrategyName))
    for name in STRATEGIES:
        assert strategy_named(name).name == name


def test_a_built_strategy_is_used_as_it_is_and_a_name_is_checked_without_building():
    sc = load_scenario(SMOKE)
    built = PaperStrategy()
    assert strategy_for(sc, built) is built
    assert strategy_name(sc) == sc.campaign.strategy
    assert strategy_name(sc, "paper") == "paper"
    with pytest.raises(ValueError, match=r"--strategy: unknown strategy 'bold'; strategies: paper"):
        strategy_name(sc, "bold")


def test_the_questions_ask_the_strategy():
    class Echo(PaperStrategy):
        def reference_cameras(self, view):
            return ["asked"]

        def next_visit(self, view):
            return "visit"

        def next_leg(self, view, goal):
            return ("leg", goal)

        def data_stops(self, view, camera, dataset, points):
            return (camera, dataset, points)

    echo = Echo()
    assert ReferenceCameras().ask(echo, None) == ["asked"]
    assert NextVisit().ask(echo, None) == "visit"
    assert NextLeg("g").ask(echo, None) == ("leg", "g")
    assert DataStops("cam1", "visit", 70).ask(echo, None) == ("cam1", "visit", 70)


# -- recoveries are events ----------------------------------------------------------------------
class _Blind(TotalStationWrapper):
    """Finds no prism in its first ``misses`` shots: the first placement of a child fails
    whole, and the child turns to show its prisms."""

    def __init__(self, inner, misses: int) -> None:
        super().__init__(inner)
        self.misses = misses

    def measure(self):
        if self.misses > 0:
            self.misses -= 1
            raise NoPrismInConeError("no prism (test)")
        return self.inner.measure()


def test_a_child_that_turns_to_show_its_prisms_is_an_event(tmp_path):
    # One failed placement takes 12 aims at the three cubes and 12 searches around them.
    results = run_scenario(
        SMOKE,
        tmp_path,
        fidelity="geometric",
        report=False,
        strategy="paper",
        adapt_rig=lambda sim: wrapped(sim.rig, total_station=lambda ts: _Blind(ts, 24)),
    )
    assert results["events"]["child_turned"] == 1
    assert results["events"]["prism_search"] == 12
    assert "child_turned" not in results["failures"]
    assert "prism_search" not in results["failures"]
    assert results["failures"]["lost_lock"] == 24
    assert [c["points"] for c in results["calibrations"]] == [70]


class _ParentBlinded:
    """After the parent's drive, the instrument finds no prism through two attempts at the
    fix (each attempt starts with an inclination reading): the parent steps aside."""

    def __init__(self) -> None:
        self.armed = False
        self.readings = 0


class _BlindAfterDrive(TotalStationWrapper):
    def __init__(self, inner, state: _ParentBlinded) -> None:
        super().__init__(inner)
        self.state = state

    def read_inclination(self):
        if self.state.armed:
            self.state.readings += 1
            if self.state.readings > 2:
                self.state.armed = False
        return self.inner.read_inclination()

    def measure(self):
        if self.state.armed:
            raise NoPrismInConeError("no prism (test)")
        return self.inner.measure()


class _Arming(MobileBaseWrapper):
    def __init__(self, inner, state: _ParentBlinded) -> None:
        super().__init__(inner)
        self.state = state

    def drive_to(self, goal_xy, goal_yaw=None):
        result = self.inner.drive_to(goal_xy, goal_yaw)
        if not self.state.readings:
            self.state.armed = True
        return result


def test_a_parent_that_steps_aside_to_see_is_an_event(tmp_path):
    state = _ParentBlinded()

    def blind_after_the_parents_drive(sim):
        return wrapped(
            sim.rig,
            total_station=lambda ts: _BlindAfterDrive(ts, state),
            base=lambda b: _Arming(b, state) if b is sim.rig.parent else b,
        )

    results = run_scenario(
        SMOKE,
        tmp_path,
        fidelity="geometric",
        report=False,
        strategy="paper",
        adapt_rig=blind_after_the_parents_drive,
    )
    assert state.readings == 3
    assert results["events"]["parent_stepped_aside"] == 1
    assert results["failures"]["parent_fix_failed"] == 2
    assert "parent_stepped_aside" not in results["failures"]
    assert [c["points"] for c in results["calibrations"]] == [70]
