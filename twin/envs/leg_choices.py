"""The paper's strategy with the legs of a travel left to the agent: the strategy the
environment's campaign runs with (:class:`LegChoices`)."""

from __future__ import annotations

import numpy as np

from twin.campaign.paper_strategy import ARRIVED, PaperStrategy
from twin.campaign.plan.legs import leg_goals
from twin.campaign.strategy import (
    CampaignView,
    Leg,
    Return,
    Visit,
)
from twin.envs.moves import MoveLayout, formation_settings


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
        return self.path.project(parent_xy, near=self.arc), self.path.project(goal.station)

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


def shorter_than(
    options: list[tuple[Leg, float] | None], s_now: float, s_failed: float
) -> list[bool]:
    """For each of :meth:`LegChoices.options`: whether it is a leg that ends nearer
    ``s_now`` (the parent's arc length, m) than ``s_failed``, where a leg taken from there
    failed (the group backed off to ``s_now``)."""
    reach = abs(s_failed - s_now) - 1e-9
    return [o is not None and abs(o[1] - s_now) < reach for o in options]
