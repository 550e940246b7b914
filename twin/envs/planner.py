"""The campaign an environment's agent plays, decision by decision: the ``campaign``
planner (:class:`CampaignPlanner`).

It runs the campaign itself (:class:`twin.envs.live_campaign.LiveCampaign`, noise-free) for
each new sequence of moves and reads back, from the process's memo of the site
(:mod:`twin.envs.plan_memo`), the moves played before. Each move gives the plan's steps the
campaign took; a batch of trials (:class:`twin.batch.execute.BatchRun`) executes them with
noise.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from twin.batch.steps import Step
from twin.campaign.plan.route import RoutePath
from twin.envs.episode import EpisodePlanner
from twin.envs.live_campaign import Decision, LiveCampaign
from twin.envs.moves import MoveLayout
from twin.envs.plan_memo import MEMO_NODES, MemoNode, PlanMemo, keep_memo, memo_for
from twin.envs.site_stations import START, Station, site_stations
from twin.scenario.schema import Scenario


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
                keep_memo(scenario, layout, budget_m, found)
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
            node = MemoNode(live.state())
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
