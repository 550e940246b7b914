"""A campaign that cannot progress ends, within bounds computed from its scenario, with the
failure ``no_progress`` naming where it was stuck (:mod:`twin.campaign.bounds`)."""

from __future__ import annotations

import itertools
import math
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import twin.sim  # noqa: F401  (headless rendering is configured before MuJoCo loads)
from twin.campaign import Campaign
from twin.campaign.bounds import (
    SHORTEST_LEG_FRACTION,
    aims_bound,
    campaign_bounds,
    legs_bound,
    stops_bound,
    travels_bound,
)
from twin.campaign.paper_strategy import PaperStrategy, PlannedStrategy, halvings
from twin.campaign.records import FAILURE, PARENT_FIX, POINT, STAGE
from twin.campaign.shooting import SEARCH_DEG, measure_child
from twin.campaign.strategies import strategy_named
from twin.campaign.strategy import Return, Stop, StopPlan
from twin.hal import TotalStation, TotalStationMeasurement
from twin.hal.readings import TiltReading
from twin.instruments.errors import NoPrismInConeError
from twin.instruments.marker import MarkerAssembly
from twin.instruments.polar import cartesian2polar
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec
from twin.localization.pose import ParentPose
from twin.scenario import Scenario, load_scenario
from twin.scenario.cross_checks import check_scenario
from twin.scenario.errors import ScenarioError
from twin.scenario.schema import Route
from twin.sim.rig import build_sim_rig
from twin.sim.world import build_world

SMOKE = Path(__file__).resolve().parents[3] / "scenarios" / "smoke.toml"

STOP_FAILURES = ("prisms_hidden", "point_unreachable", "point_skipped")
"""The failures of a data stop that gave no point: one of them per such stop."""


class _Log:
    """The campaign's records, in order: (topic, record)."""

    def __init__(self) -> None:
        self.records: list[tuple[str, object]] = []

    def record(self, topic: str, record: object, timestamp: float) -> None:
        self.records.append((topic, record))

    def failures(self, kind: str | None = None) -> list:
        return [r for t, r in self.records if t == FAILURE and kind in (None, r.kind)]

    def by_stage(self) -> list[tuple[str, Counter]]:
        """Each stage as it started (``travel``, ``return``, ``reference``, ``station``)
        with the count of its parent's fixes (one per leg) and data stops."""
        out: list[tuple[str, Counter]] = []
        for topic, rec in self.records:
            if topic == STAGE:
                out.append((rec.stage, Counter()))
            elif out and topic == PARENT_FIX:
                out[-1][1]["legs"] += 1
            elif out and (topic == POINT or (topic == FAILURE and rec.kind in STOP_FAILURES)):
                out[-1][1]["stops"] += 1
        return out


def _smoke(
    waypoints=((0.0, 0.0), (4.0, 0.0)),
    return_to_start: bool = False,
    points: int = 70,
    **campaign,
) -> Scenario:
    sc = load_scenario(SMOKE)
    settings_ = {"reference_points": points, "station_points": points, "min_points": 8}
    return sc.model_copy(
        update={
            "route": Route(waypoints=tuple(waypoints), return_to_start=return_to_start),
            "campaign": sc.campaign.model_copy(update={**settings_, **campaign}),
        }
    )


RETURN = ((0.0, 0.0), (4.0, 0.0), (0.0, 0.0))
"""The smoke room's route out to x = 4 m and back along itself to the start."""


def _run(sc: Scenario, seed: int, strategy=None, noise: bool = True):
    """(campaign, log, outcome, seconds) of a geometric run."""
    if not noise:
        sc = sc.without_noise()
    sim = build_sim_rig(build_world(sc), "geometric", seed=seed)
    log = _Log()
    try:
        campaign = Campaign(sim.rig, sc, log, strategy=strategy)
        start = time.perf_counter()
        outcome = campaign.run()
        seconds = time.perf_counter() - start
    finally:
        sim.close()
    return campaign, log, outcome, seconds


def _within_bounds(campaign: Campaign, log: _Log) -> None:
    """Every loop the run took stayed within its bound."""
    bounds = campaign.bounds
    stages = log.by_stage()
    for stage, counts in stages:
        if stage in ("travel", "return"):
            assert counts["legs"] <= bounds.legs, (stage, counts)
        else:
            assert counts["stops"] <= bounds.stops, (stage, counts)
    assert sum(stage in ("travel", "return") for stage, _ in stages) <= bounds.travels
    assert campaign.travel.drives <= bounds.drives


# -- the bounds themselves -------------------------------------------------------------------------
def test_the_bounds_follow_from_the_scenario():
    sc = _smoke(RETURN, return_to_start=True)
    bounds = campaign_bounds(sc)
    # 8 m of route in legs of 0.15 x 5 m, twice, and one leg off the route.
    assert SHORTEST_LEG_FRACTION == 0.15
    assert bounds.legs == legs_bound(8.0, 5.0, 2.0) == math.ceil(2 * 8.0 / 0.75) + 1 == 23
    assert bounds.travels == travels_bound(1, 2.0) == 8  # one visit and the return, x 2 x 2
    assert bounds.stops == stops_bound(70, 2.0) == 140
    # The slack scales every bound; a longer route or a shorter step allows more legs.
    looser = campaign_bounds(_smoke(RETURN, True, progress_slack=4.0))
    assert looser.legs == math.ceil(4 * 8.0 / 0.75) + 1 == 44
    assert (looser.travels, looser.stops) == (2 * bounds.travels, 2 * bounds.stops)
    assert looser.drives > 2 * bounds.drives
    assert legs_bound(16.0, 5.0, 2.0) == legs_bound(8.0, 2.5, 2.0) == 44
    # A travel along the whole route in its shortest legs fits, twice over.
    assert bounds.legs - 1 >= 2 * 8.0 / (SHORTEST_LEG_FRACTION * 5.0)


class _Station(TotalStation):
    """Locks a prism (at ``prism``, levelled frame) on the aims numbered in ``locks`` only."""

    spec = TotalStationSpec()
    inclinometer = InclinometerSpec()

    def __init__(self, prism: np.ndarray, locks: set[int]) -> None:
        self.prism, self.locks, self.aims = prism, locks, 0

    def point(self, target_level) -> None:
        self.aims += 1

    def measure(self) -> TotalStationMeasurement:
        if self.aims - 1 not in self.locks:
            raise NoPrismInConeError("no prism (test)")
        return TotalStationMeasurement.from_polar(cartesian2polar(self.prism), 0.0)

    def read_inclination(self) -> TiltReading:
        return TiltReading(0.0, 0.0, 0.0)

    def close(self) -> None:
        pass


class _Quiet:
    def failure(self, kind, message, details) -> None:
        pass

    def event(self, kind, message, details) -> None:
        pass


@pytest.mark.parametrize("retries", [0, 3, 10])
def test_the_aims_of_one_measurement_stay_within_their_bound(retries):
    marker = MarkerAssembly()
    parent = ParentPose(0.0, np.zeros(3))
    child = np.array([3.0, 0.5, 0.0])
    search = 3 * (retries + 1)  # the aims at the cubes, every one lost
    cases = {
        "nothing answers": (set(), search + len(SEARCH_DEG)),
        # The prism search's last aim finds one prism; every re-aim from it fails.
        "the search's last aim": ({search + len(SEARCH_DEG) - 1}, aims_bound(retries) // 2),
        # The first aim locks; the other cubes and the re-aims from it are lost.
        "one prism": ({0}, 1 + 2 * (retries + 1) + 18),
    }
    for name, (locks, expected) in cases.items():
        station = _Station(np.array([3.0, 0.5, 0.1]), locks)
        obs = measure_child(station, "child1", parent, child, marker, -0.4, retries, _Quiet(), None)
        assert obs is None, name
        assert station.aims == expected <= aims_bound(retries), name


# -- the scenario that drove back and forth --------------------------------------------------------
@pytest.mark.parametrize(
    ("strategy", "noise"), [("planned", True), ("planned", False), ("paper", True)]
)
def test_a_return_along_the_way_out_ends_with_a_named_failure(strategy, noise):
    # The smoke room, out to x = 4 m and back to the start along the same line. The
    # group's place on the route after a leg was the first of the two equally near (out
    # and back): on its way back it was put on its way out, drove round the turn at
    # x = 4 m again, and again, about 11,000 times. Now the return goes on, and where the
    # children have no room ahead of the parent before the west wall they stand where
    # both of its stations see them.
    sc = _smoke(RETURN, return_to_start=True)
    campaign, log, outcome, seconds = _run(
        sc, seed=1, strategy=strategy_named(strategy), noise=noise
    )
    assert seconds < 30.0
    _within_bounds(campaign, log)
    assert outcome.failures["no_progress"] == 0
    assert outcome.failures["no_formation"] == outcome.failures["campaign_aborted"] == 0
    stages = [stage for stage, _ in log.by_stage()]
    assert stages[-2:] == ["return", "done"]
    # Back past the turn: the parent stands on the way back, nearer the start than x = 4.
    assert campaign.cps.parent.translation[0] < 3.5


class _FirstPass(PlannedStrategy):
    """The planned strategy placing the group, after each leg, at the first of the route's
    points nearest the parent (as it did): a return along the way out never gets back."""

    def _follow_parent(self, parent_xy) -> None:
        if self._reached_s is not None:
            self._arc = self.path.project(parent_xy)
            self._reached_s = None


def test_a_travel_that_never_arrives_ends_with_no_progress():
    sc = _smoke(RETURN, return_to_start=True)
    campaign, log, outcome, seconds = _run(sc, seed=1, strategy=_FirstPass())
    assert seconds < 30.0
    _within_bounds(campaign, log)
    (stuck,) = log.failures("no_progress")
    legs = campaign.bounds.legs
    assert stuck.details["stage"] == "return"
    assert stuck.details["count"] == stuck.details["bound"] == legs
    x, y = stuck.details["x"], stuck.details["y"]
    assert 2.0 < x < 4.0  # driving back and forth between 2.6 and 4 m
    assert abs(y) < 0.2
    assert f"no progress in the return stage, the parent at ({x:.2f}, {y:.2f}) m" in stuck.message
    assert f"{legs} legs back" in stuck.message
    assert outcome.failures["campaign_aborted"] == 1
    assert log.by_stage()[-2] == ("return", Counter(legs=legs))


# -- the other loops -------------------------------------------------------------------------------
class _Again(PaperStrategy):
    """Goes back to where the parent stands, for ever."""

    def next_visit(self, view):
        return Return(view.parent.translation[:2].copy(), view.parent.yaw, "again")


def test_a_strategy_that_keeps_asking_for_travels_ends_with_no_progress():
    sc = _smoke(reference_cameras=())
    campaign, log, outcome, _ = _run(sc, seed=1, strategy=_Again())
    (stuck,) = log.failures("no_progress")
    travels = campaign.bounds.travels
    assert (stuck.details["count"], stuck.details["bound"]) == (travels, travels)
    assert f"{travels} travels" in stuck.message
    assert sum(stage == "return" for stage, _ in log.by_stage()) == travels
    assert outcome.failures["campaign_aborted"] == 1


class _Unreachable(PaperStrategy):
    """Every data stop inside the pillar, as many as asked for and more."""

    def data_stops(self, view, camera, dataset, points):
        return StopPlan(view.children[0], [Stop(np.array([6.5, -2.2]), 0.0)] * (3 * points))


def test_a_data_set_whose_stops_give_nothing_ends_with_no_progress():
    sc = _smoke(points=8)
    _, log, outcome, _ = _run(sc, seed=1, strategy=_Unreachable())
    most = stops_bound(8, 2.0)
    stuck = log.failures("no_progress")
    assert [s.details["stage"] for s in stuck] == ["reference", "station"]
    assert all(s.details["count"] == most and s.camera == "cam1" for s in stuck)
    assert "stops for cam1's reference data (0 of 8 points)" in stuck[0].message
    assert [c for stage, c in log.by_stage() if stage in ("reference", "station")][-2:] == [
        Counter(stops=most),
        Counter(stops=most),
    ]
    # The data sets end with what they have; the campaign goes on to its end.
    assert outcome.failures["campaign_aborted"] == 0
    assert log.by_stage()[-1][0] == "done"


def test_drives_beyond_the_campaign_bound_end_it_with_no_progress():
    sc = _smoke(points=8)
    sim = build_sim_rig(build_world(sc), "geometric", seed=1)
    log = _Log()
    try:
        campaign = Campaign(sim.rig, sc, log)
        campaign.travel.max_drives = 5
        outcome = campaign.run()
    finally:
        sim.close()
    (stuck,) = log.failures("no_progress")
    assert stuck.details["what"] == "drives of the robots"
    assert (stuck.details["count"], campaign.travel.drives) == (5, 5)
    assert outcome.failures["campaign_aborted"] == 1


# -- any smoke-sized campaign ----------------------------------------------------------------------
corner = st.tuples(st.floats(-1.3, 5.5), st.floats(-2.3, 2.3))


# A random route may give a visit few or nearly coplanar points: the calibration says so,
# which is not what this property is about.
@pytest.mark.filterwarnings("ignore::calib.checks.DegenerateGeometryWarning")
@settings(
    max_examples=25,
    deadline=None,
    suppress_health_check=[HealthCheck.filter_too_much, HealthCheck.too_slow],
)
@given(
    corners=st.lists(corner, min_size=1, max_size=3),
    back=st.booleans(),
    seed=st.integers(0, 2**16),
    strategy=st.sampled_from(["planned", "paper"]),
)
def test_any_route_in_the_smoke_room_ends_within_its_bounds(corners, back, seed, strategy):
    waypoints = [(0.0, 0.0), *corners] + ([(0.0, 0.0)] if back else [])
    assume(all(math.dist(a, b) > 0.3 for a, b in itertools.pairwise(waypoints)))
    sc = _smoke(waypoints, back, points=8)
    assume(not check_scenario(sc))
    campaign, log, outcome, _ = _run(sc, seed, strategy=strategy_named(strategy))
    _within_bounds(campaign, log)
    assert log.by_stage()[-1][0] == "done"
    if outcome.failures["campaign_aborted"]:
        # Ended by a named failure, recorded before the abort.
        kinds = [f.kind for f in log.failures()]
        assert kinds[-1] == "campaign_aborted"
        assert len(kinds) > 1
    for stuck in log.failures("no_progress"):
        assert stuck.details["count"] == stuck.details["bound"]
        assert f"no progress in the {stuck.details['stage']} stage" in stuck.message


def test_a_leg_is_halved_a_bounded_number_of_times():
    # Down to 30 % of a 5 m step: a 5 m leg twice (2.5, then 1.25 m), a 1 m leg not at all.
    assert halvings(5.0, 1.5) == 2
    assert halvings(1.0, 1.5) == halvings(1.5, 1.5) == 0
    assert halvings(1.5 * 2**10 + 1e-9, 1.5) == 11
    assert halvings(float("nan"), 1.5) == halvings(float("inf"), 1.5) == 0


@pytest.mark.parametrize("value", ["0.5", "101", "nan"])
def test_a_slack_out_of_range_is_refused_with_its_key(tmp_path, value):
    path = tmp_path / "slack.toml"
    path.write_text(SMOKE.read_text() + f"\n[campaign]\nprogress_slack = {value}\n")
    with pytest.raises(ScenarioError) as refused:
        load_scenario(path)
    assert "campaign.progress_slack" in str(refused.value)
    assert str(path) in str(refused.value)
