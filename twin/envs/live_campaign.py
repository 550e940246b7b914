"""The noise-free campaign of a scenario, advanced by an agent's moves
(:class:`LiveCampaign`), and where it stands at each decision (:class:`Decision`).

The campaign runs as :class:`twin.batch.steps.PlanSession` (the campaign itself at the
geometric fidelity, without noise) and answers the questions that are not the agent's with
the paper's strategy (which cameras get a reference data set, where the child stops for a
camera's data, the leg that is not needed once the parent is at its station). The agent
answers the others with a move of :class:`twin.envs.moves.MoveLayout`: the legs of a
travel and where to go between travels. Each answer gives the plan's steps the campaign
took.

The moves allowed at each decision (the mask) are exact: a leg is allowed when its
formation has room (the planner has already placed the children for it), a travel when
its station is known and in reach of the distance budget.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from twin.batch.steps import PlanSession, Step
from twin.campaign.paper_strategy import ARRIVED
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
from twin.envs.episode import LEG, VISIT, calibrated_since_moved, visit_mask
from twin.envs.leg_choices import LegChoices, shorter_than
from twin.envs.moves import MoveLayout
from twin.envs.site_stations import START, Station, site_stations
from twin.scenario.schema import Scenario


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
        # Each camera's last calibration: the parent's travel then, m (recorded at the
        # decision that follows it). Calibrating it again needs the group to have moved.
        self.calibrated_at: dict[str, float] = {}
        self._calibrating: str | None = None
        self.goal: Station | None = None
        self.decision: str | None = None
        self.mask = np.zeros(layout.size, dtype=bool)
        self._legs: list[tuple[Leg, float] | None] = []
        self._taken_s: float | None = None  # where the leg taken last was to end, m
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
        s_now = path.project(xy, near=self.strategy.arc)
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
                self._taken_s = s_next
                self._answer(leg)
        elif action == layout.calibrate:
            here = self.here()
            assert here is not None
            station = self.stations[here]
            camera = station.camera
            assert camera is not None
            self.visits[camera] = self.visits.get(camera, 0) + 1
            self._calibrating = camera
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
                allowed = [leg is not None for leg in self._legs]
                if question.failed is not None and self._taken_s is not None:
                    # The leg taken failed and the group backed off: a shorter one, where
                    # one has room (else the same again, as the campaign's strategy does
                    # once it has shortened the leg to its shortest).
                    s_now = self.strategy.position(self.view, question.goal)
                    if s_now is not None:
                        shorter = shorter_than(self._legs, s_now[0], self._taken_s)
                        allowed = shorter if any(shorter) else allowed
                self.mask[:] = False
                self.mask[: self.layout.legs] = allowed
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
        travelled = self.session.travelled
        if self._calibrating is not None:
            self.calibrated_at[self._calibrating], self._calibrating = travelled, None
        here = self.here()
        camera = None if here is None else self.stations[here].camera
        visit_mask(
            self.mask,
            self.layout,
            self.order,
            here,
            camera is not None
            and not calibrated_since_moved(self.calibrated_at, camera, travelled),
            lambda name: self.route_distance(self.stations[name]),
            self.budget_m - self.session.travelled,
        )

    def close(self) -> None:
        """Free the campaign's world."""
        self.session.close()
