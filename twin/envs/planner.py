"""The campaign an environment's agent plays: its noise-free plan, decision by decision.

:class:`CampaignPlanner` runs the campaign (:class:`twin.batch.plan.PlanSession`: the
campaign itself at the geometric fidelity, without noise) and answers the questions that
are not the agent's with the paper's strategy (which cameras get a reference data set,
where the child stops for a camera's data, the leg that is not needed once the parent is
at its station). The agent answers the others with a move of :class:`twin.envs.moves.
MoveLayout`: the legs of a travel and where to go between travels. Each answer gives the
plan's steps the campaign took; a batch of trials (:class:`twin.batch.execute.BatchRun`)
executes them with noise.

The moves allowed at each decision (the mask) are exact: a leg is allowed when its
formation has room (the planner has already placed the children for it), a travel when
its station is known and in reach of the distance budget.

The campaign is deterministic given the moves, so a site's campaigns are kept, as a tree
of the moves played, in a memo (:class:`PlanMemo`) that the episodes of a process share:
moves played before are read back, and only new ones run the campaign.
"""

from __future__ import annotations

import abc
import math
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from twin.batch.plan import BatchPlan, PlanSession, Step
from twin.campaign.paper_strategy import ARRIVED, PaperStrategy
from twin.campaign.plan.legs import leg_goals
from twin.campaign.plan.route import RoutePath
from twin.campaign.strategy import (
    CampaignView,
    DataStops,
    Leg,
    NextLeg,
    NextVisit,
    NoLeg,
    ReferenceCameras,
    Return,
    Visit,
)
from twin.envs.moves import MoveLayout, formation_settings
from twin.scenario.schema import CalibrationVisit, Scenario

if TYPE_CHECKING:
    from twin.envs.stands import StandSite

__all__ = [
    "START",
    "CampaignPlanner",
    "Decision",
    "EpisodePlanner",
    "LegChoices",
    "PlanMemo",
    "Station",
    "memo_for",
]

LEG = "leg"
"""A decision about the next leg of a travel."""

VISIT = "visit"
"""A decision between travels: calibrate here, go somewhere, or end."""

MEMO_NODES = 200_000
"""Most decisions a site's memo keeps (beyond, new ones are computed and not kept)."""

MEMO_SITES = 8
"""Sites whose memos a process keeps (the least recently used is dropped)."""


START = "start"
"""The name of the first station."""


@dataclass(frozen=True)
class Station:
    """A place the group can travel to: a camera's calibration station, or the start.

    Attributes:
        name: ``<camera>@<n>`` (the camera's n-th station in the scenario's visits), or
            ``start``. camera: the camera calibrated there (None at the start).
        xy: (2,) where the parent stands, m in W. yaw: its heading there, rad.
        arc: the station's arc length on the route, m.
    """

    name: str
    camera: str | None
    xy: NDArray[np.float64]
    yaw: float
    arc: float


class LegChoices(PaperStrategy):
    """The paper's strategy, with the legs of a travel chosen one at a time by the caller.

    The paper's answers serve the questions the agent is not asked (reference cameras,
    data stops); :meth:`options` plans the next leg in every formation and step of a
    layout, and :meth:`take` commits one.
    """

    name = "agent"

    def position(self, view: CampaignView, goal: Visit | Return) -> tuple[float, float] | None:
        """(arc length of the parent, of the goal's station) on the route, m; None when the
        parent is at the station."""
        parent_xy = view.parent.translation[:2]
        self._follow_parent(parent_xy)
        if np.linalg.norm(goal.station - parent_xy) < ARRIVED:
            return None
        return self.path.project(parent_xy, near=self._arc), self.path.project(goal.station)

    def options(
        self, view: CampaignView, goal: Visit | Return, layout: MoveLayout
    ) -> list[tuple[Leg, float] | None]:
        """For each leg value of ``layout``: the leg and the arc length it ends at, or None
        where its formation has no room. The parent must not be at the station."""
        where = self.position(view, goal)
        if where is None:
            raise ValueError("the parent is at the station: no leg to plan")
        s_now, s_goal = where
        direction = 1.0 if s_goal >= s_now else -1.0
        base = view.scenario.campaign.formation
        ends = [
            leg_goals(self.path, s_now, s_goal, factor * base.step)
            for factor in layout.step_factors
        ]
        out: list[tuple[Leg, float] | None] = []
        for formation in layout.formations:
            form = formation_settings(formation, base)
            planned: dict[tuple[float, bool], Leg | None] = {}  # steps that end alike
            for leg_ends in ends:
                key = (leg_ends[0], len(leg_ends) == 1)
                if key not in planned:
                    found = self.leg_between(view, goal, s_now, *key, direction, form)
                    planned[key] = None if found is None else found[1]
                leg = planned[key]
                out.append(None if leg is None else (leg, leg_ends[0]))
        return out

    def take(self, s_next: float) -> None:
        """The leg to arc length ``s_next`` is taken."""
        self._reached_s = s_next


@dataclass(frozen=True)
class Decision:
    """Where the campaign stands at a decision (or at its end).

    Attributes:
        decision: ``leg``, ``visit``, or None once the campaign is over.
        mask: (n,) the moves allowed.
        time: the campaign's time, s. travelled: the parent's travel, m.
        here: the station the parent stands at, or None.
        goal: the station the group travels to (during a travel), or None.
        distances: each station's route distance from the parent, m.
    """

    decision: str | None
    mask: NDArray[np.bool_]
    time: float
    travelled: float
    here: str | None
    goal: str | None
    distances: dict[str, float]


def visit_stations(scenario: Scenario, stations: dict[str, Station]) -> list[str]:
    """The station of each of the scenario's visits, in order, by name."""
    return [
        next(n for n, s in stations.items() if _is_visits(s, visit))
        for visit in scenario.calibration.visits
    ]


def _is_visits(station: Station, visit: CalibrationVisit) -> bool:
    """Whether ``station`` is where the scenario's ``visit`` calibrates."""
    return (
        station.camera == visit.camera
        and np.array_equal(station.xy, np.asarray(visit.station, dtype=float))
        and station.yaw == math.radians(visit.yaw_deg)
    )


def site_stations(scenario: Scenario, path: RoutePath) -> dict[str, Station]:
    """The stations of the scenario's visits, in their order (a station visited twice
    counts once), then the start."""
    stations: dict[str, Station] = {}
    seen: dict[str, int] = {}
    for visit in scenario.calibration.visits:
        if any(_is_visits(s, visit) for s in stations.values()):
            continue
        xy = np.asarray(visit.station, dtype=float)
        seen[visit.camera] = seen.get(visit.camera, 0) + 1
        name = f"{visit.camera}@{seen[visit.camera]}"
        stations[name] = Station(
            name, visit.camera, xy, math.radians(visit.yaw_deg), path.project(xy)
        )
    start = scenario.robots.parent
    xy = np.asarray(start.start_xy, dtype=float)
    stations[START] = Station(START, None, xy, math.radians(start.start_yaw_deg), path.project(xy))
    return stations


def visit_mask(
    mask: NDArray[np.bool_],
    layout: MoveLayout,
    order: tuple[str, ...],
    here: str | None,
    calibrate: bool,
    distance: Callable[[str], float],
    left: float,
) -> None:
    """Set ``mask`` (n,) to the moves allowed between travels: ``calibrate`` where the
    camera of the station ``here`` can be calibrated, a travel to each other station of
    ``order`` (``go_to``) and back to the start whose route ``distance`` (by the station's
    name, m) fits in what is ``left`` of the budget (m), and ``end``."""
    mask[:] = False
    mask[layout.calibrate] = calibrate
    for k, name in enumerate(order):
        if name != here:
            mask[layout.go_to(k)] = distance(name) <= left
    if here != START:
        mask[layout.return_start] = distance(START) <= left
    mask[layout.end] = True


class LiveCampaign:
    """The noise-free campaign of a scenario (a live :class:`PlanSession`), advanced by an
    agent's moves.

    Args:
        scenario: the site and its campaign settings (its noise is the instrument's
            advertised noise; the plan itself is noise-free).
        layout: the moves.
        budget_m: the parent's travel allowed, m: a travel is allowed while its route
            distance fits in what is left.
    """

    def __init__(self, scenario: Scenario, layout: MoveLayout, budget_m: float) -> None:
        self.scenario = scenario
        self.layout = layout
        self.budget_m = budget_m
        self.strategy = LegChoices()
        self.session = PlanSession(scenario, self.strategy)
        self.stations = site_stations(scenario, self.strategy.path)
        self.order = tuple(name for name in self.stations if name != START)
        self.visits: dict[str, int] = {}
        self.goal: Station | None = None
        self.decision: str | None = None
        self.mask = np.zeros(layout.size, dtype=bool)
        self._legs: list[tuple[Leg, float] | None] = []
        self.pending: list[Step] = []
        self._advance()

    @property
    def view(self) -> CampaignView:
        """What the campaign knows (noise-free)."""
        return self.session.view

    def here(self) -> str | None:
        """The station the parent stands at, or None (the nearest of those within
        reach)."""
        xy = self.view.parent.translation[:2]
        near = {n: float(np.linalg.norm(st.xy - xy)) for n, st in self.stations.items()}
        name = min(near, key=near.__getitem__)
        return name if near[name] < ARRIVED else None

    def route_distance(self, station: Station) -> float:
        """The parent's travel along the route to a station, m."""
        xy = self.view.parent.translation[:2]
        path = self.strategy.path
        s_now = path.project(xy, near=self.strategy._arc)
        return (
            abs(station.arc - s_now)
            + float(np.linalg.norm(path.at(s_now) - xy))
            + float(np.linalg.norm(path.at(station.arc) - station.xy))
        )

    def state(self) -> Decision:
        """Where the campaign stands now."""
        return Decision(
            self.decision,
            self.mask.copy(),
            self.session.time,
            self.session.travelled,
            self.here(),
            None if self.goal is None else self.goal.name,
            {name: self.route_distance(st) for name, st in self.stations.items()},
        )

    def act(self, action: int) -> tuple[Step, ...]:
        """Take an allowed move; the plan's steps until the next decision.

        Raises:
            ValueError: ``action`` is not in the action space
                (:meth:`twin.envs.moves.MoveLayout.check`), or the move is not allowed now
                (see :attr:`mask`).
            RuntimeError: the campaign is over.
        """
        if self.decision is None:
            raise RuntimeError("the campaign is over: no move to take")
        action = self.layout.check(action)
        if not self.mask[action]:
            raise ValueError(f"{self.layout.describe(action)} is not allowed now")
        layout = self.layout
        if self.decision == LEG:
            if action == layout.end:
                self._answer(NoLeg("no_formation", "no room for any formation", "no formation"))
            else:
                chosen = self._legs[action]
                assert chosen is not None
                leg, s_next = chosen
                self.strategy.take(s_next)
                self._answer(leg)
        elif action == layout.calibrate:
            here = self.here()
            assert here is not None
            station = self.stations[here]
            camera = station.camera
            assert camera is not None
            self.visits[camera] = self.visits.get(camera, 0) + 1
            self._answer(Visit(camera, self.visits[camera], station.xy.copy(), station.yaw))
        elif action == layout.end:
            self._answer(None)
        else:
            name = START if action == layout.return_start else self.order[action - layout.go_to(0)]
            station = self.stations[name]
            reason = "back to the start" if name == START else f"to station {name}"
            self.goal = station
            self._answer(Return(station.xy.copy(), station.yaw, reason))
        return self.take_pending()

    def take_pending(self) -> tuple[Step, ...]:
        """The plan's steps taken since the last call (at the start: the reference data)."""
        steps, self.pending = tuple(self.pending), []
        return steps

    def _answer(self, answer: object) -> None:
        self.pending.extend(self.session.answer(answer))
        self._advance()

    def _advance(self) -> None:
        """Answer the questions that are not the agent's until one is, or the end."""
        session = self.session
        while not session.done:
            question = session.question
            if isinstance(question, (ReferenceCameras, DataStops)):
                self.pending.extend(session.answer(session.suggested()))
                continue
            if isinstance(question, NextLeg):
                if self.strategy.position(self.view, question.goal) is None:
                    self.pending.extend(session.answer(None))  # there: no leg
                    continue
                self._legs = self.strategy.options(self.view, question.goal, self.layout)
                self.mask[:] = False
                self.mask[: self.layout.legs] = [leg is not None for leg in self._legs]
                if not self.mask.any():
                    self.mask[self.layout.end] = True
                self.decision = LEG
                return
            assert isinstance(question, NextVisit), question
            self.goal = None
            self._visit_mask()
            self.decision = VISIT
            return
        self.decision = None
        self.mask[:] = False

    def _visit_mask(self) -> None:
        here = self.here()
        visit_mask(
            self.mask,
            self.layout,
            self.order,
            here,
            here is not None and self.stations[here].camera is not None,
            lambda name: self.route_distance(self.stations[name]),
            self.budget_m - self.session.travelled,
        )

    def close(self) -> None:
        """Free the campaign's world."""
        self.session.close()


@dataclass
class _Node:
    """A decision of the memo, and the moves taken from it so far."""

    state: Decision
    moves: dict[int, tuple[tuple[Step, ...], _Node]] = field(default_factory=dict)


class PlanMemo:
    """The noise-free campaign of one site for every sequence of moves played so far.

    The campaign is deterministic given the moves: a sequence played once is not computed
    again (its steps and decisions are read back), which makes a policy that repeats its
    moves, or a search that tries moves from the same decisions, cheap after the first
    episode. At most :data:`MEMO_NODES` decisions are kept.
    """

    def __init__(self, plan: BatchPlan, start: tuple[Step, ...], state: Decision) -> None:
        self.plan = plan
        self.start = start
        self.root = _Node(state)
        self.nodes = 1


_MEMOS: OrderedDict[tuple[str, MoveLayout, float], PlanMemo] = OrderedDict()


def memo_for(scenario: Scenario, layout: MoveLayout, budget_m: float) -> PlanMemo | None:
    """The process's memo of a site (None when there is none yet)."""
    key = (scenario.model_dump_json(), layout, budget_m)
    memo = _MEMOS.get(key)
    if memo is not None:
        _MEMOS.move_to_end(key)
    return memo


def _keep_memo(scenario: Scenario, layout: MoveLayout, budget_m: float, memo: PlanMemo) -> None:
    _MEMOS[(scenario.model_dump_json(), layout, budget_m)] = memo
    while len(_MEMOS) > MEMO_SITES:
        _MEMOS.popitem(last=False)


def clear_memos() -> None:
    """Forget every site's memo (the next episodes compute their campaigns again)."""
    _MEMOS.clear()


class EpisodePlanner(abc.ABC):
    """What an environment asks of the campaign it plays, decision by decision (the
    campaign itself: :class:`CampaignPlanner`; a site's table:
    :class:`twin.envs.stands.StandPlanner`).

    Attributes:
        layout: the moves. budget_m: the parent's travel allowed, m.
        stations: the calibration stations and ``start``, by name. order: the calibration
            stations' names in the order of ``go_to``.
    """

    layout: MoveLayout
    budget_m: float
    stations: dict[str, Station]
    order: tuple[str, ...]
    decision: str | None  # ``leg``, ``visit``, or None once the campaign is over
    _pending: tuple[Step, ...]

    @property
    @abc.abstractmethod
    def memo(self) -> PlanMemo | StandSite:
        """What the planners of a site in one process share (its plan, its start)."""

    @property
    def plan(self) -> BatchPlan:
        """The campaign's plan before its first step."""
        return self.memo.plan

    @property
    @abc.abstractmethod
    def mask(self) -> NDArray[np.bool_]:
        """(n,) the moves allowed now (read-only)."""

    @abc.abstractmethod
    def here(self) -> str | None:
        """The station the parent stands at, or None."""

    @abc.abstractmethod
    def _take(self, action: int) -> tuple[Step, ...]:
        """Take an allowed move (checked); the plan's steps until the next decision."""

    @property
    def done(self) -> bool:
        """Whether the campaign is over."""
        return self.decision is None

    def here_camera(self) -> str | None:
        """The camera whose station the parent stands at, or None."""
        here = self.here()
        return None if here is None else self.stations[here].camera

    def take_pending(self) -> tuple[Step, ...]:
        """The plan's steps before the first decision (the reference data), once."""
        steps, self._pending = self._pending, ()
        return steps

    def act(self, action: int) -> tuple[Step, ...]:
        """Take an allowed move; the plan's steps until the next decision.

        Raises:
            ValueError: ``action`` is not in the action space
                (:meth:`twin.envs.moves.MoveLayout.check`), or the move is not allowed now
                (see :attr:`mask`).
            RuntimeError: the campaign is over.
        """
        if self.done:
            raise RuntimeError("the campaign is over: no move to take")
        action = self.layout.check(action)
        if not self.mask[action]:
            raise ValueError(f"{self.layout.describe(action)} is not allowed now")
        return self._take(action)


class CampaignPlanner(EpisodePlanner):
    """The noise-free campaign of a site, advanced by an agent's moves, read from the site's
    memo where the moves were played before and computed (:class:`LiveCampaign`) where not.

    Args:
        scenario: the site and its campaign settings.
        layout: the moves.
        budget_m: the parent's travel allowed, m.
        memo: whether to use (and grow) the process's memo of the site.

    Attributes:
        plan: the campaign's plan before its first step (its robots, cameras, LED radii).
        stations: the calibration stations and ``start``, by name. order: the calibration
            stations' names in the order of ``go_to``.
    """

    def __init__(
        self, scenario: Scenario, layout: MoveLayout, budget_m: float, memo: bool = True
    ) -> None:
        self.scenario, self.layout, self.budget_m = scenario, layout, budget_m
        self.stations = site_stations(scenario, RoutePath(scenario.route.waypoints))
        self.order = tuple(name for name in self.stations if name != START)
        if len(self.order) > layout.max_stations:
            raise ValueError(
                f"{scenario.name}: {len(self.order)} stations, more than max_stations = "
                f"{layout.max_stations}"
            )
        self._live: LiveCampaign | None = None
        self._synced = 0  # moves of the history the live campaign has taken
        self._history: list[int] = []
        found = memo_for(scenario, layout, budget_m) if memo else None
        if found is None:
            live = self._live = LiveCampaign(scenario, layout, budget_m)
            found = PlanMemo(live.session.plan, live.take_pending(), live.state())
            if memo:
                _keep_memo(scenario, layout, budget_m, found)
        self._memo = found
        self._node = found.root
        self._pending: tuple[Step, ...] = found.start
        self.computed = 0  # moves this planner computed (not read from the memo)

    # -- where the campaign stands ---------------------------------------------------------------
    @property
    def memo(self) -> PlanMemo:
        """The site's memo (planners of one site in one process share it)."""
        return self._memo

    @property
    def state(self) -> Decision:
        """Where the campaign stands."""
        return self._node.state

    @property
    def decision(self) -> str | None:
        """``leg``, ``visit``, or None once the campaign is over."""
        return self._node.state.decision

    @property
    def mask(self) -> NDArray[np.bool_]:
        """(n,) the moves allowed now (read-only)."""
        mask = self._node.state.mask
        mask.flags.writeable = False
        return mask

    @property
    def time(self) -> float:
        """The campaign's time so far, s."""
        return self._node.state.time

    @property
    def travelled(self) -> float:
        """The parent's planned travel so far, m."""
        return self._node.state.travelled

    def here(self) -> str | None:
        """The station the parent stands at, or None."""
        return self._node.state.here

    @property
    def goal_station(self) -> Station | None:
        """The station the group travels to, during a travel."""
        goal = self._node.state.goal
        return None if goal is None else self.stations[goal]

    def route_distance(self, station: Station) -> float:
        """The parent's travel along the route to a station, m."""
        return self._node.state.distances[station.name]

    # -- moves ----------------------------------------------------------------------------
    def _take(self, action: int) -> tuple[Step, ...]:
        known = self._node.moves.get(action)
        if known is None:
            live = self._catch_up()
            steps = live.act(action)
            self._synced += 1
            self.computed += 1
            node = _Node(live.state())
            if self._memo.nodes < MEMO_NODES:
                self._node.moves[action] = (steps, node)
                self._memo.nodes += 1
        else:
            steps, node = known
        self._history.append(action)
        self._node = node
        return steps

    def _catch_up(self) -> LiveCampaign:
        """The live campaign, having taken every move of the history."""
        if self._live is None:
            self._live = LiveCampaign(self.scenario, self.layout, self.budget_m)
            self._live.take_pending()
            self._synced = 0
        live = self._live
        for action in self._history[self._synced :]:
            live.act(action)
        self._synced = len(self._history)
        return live

    def close(self) -> None:
        """Free the live campaign's world, if one was made."""
        if self._live is not None:
            self._live.close()
            self._live = None
