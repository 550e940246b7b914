"""The campaign an environment's agent plays, read from a table of the site: the ``stands``
planner, fast enough for random moves.

The campaign planner (:mod:`twin.envs.planner`) runs the campaign itself for every new
sequence of moves, which costs about a tenth of a second a decision: fine for policies
that repeat their moves, far too slow for exploration. This planner plays the same moves
on a site's table, computed once per site and process
(:class:`twin.envs.stand_site.StandSite`: its stands, its legs, its stations' data).

What the table leaves out, which the campaign planner keeps (the price of its speed):

- the waiting child is not checked for hiding the far child's prisms (a formation may be
  allowed that the campaign would refuse; the batch does not simulate lost locks);
- the sight margins come from the trial's own parent covariance, rounded up to
  :data:`STD_STEP` (the campaign plans from its noise-free covariance);
- the children keep their order along the route (the one ahead moves first), by the
  direction of travel;
- a station's data stops and calibration are those the paper's campaign took there,
  whatever formation the group arrived in (its anchor child stood where the paper's
  left it); a station the paper's run could not calibrate at cannot be calibrated at;
- time: each robot's straight travel at its top speed from where it stood (the first
  leg from where the reference data left it), as the geometric clock counts it, plus the
  shots' time of a leg measured on the site's paper run; a station's data take the time
  they took in that run.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from twin.batch.steps import (
    Step,
)
from twin.campaign.paper_strategy import ARRIVED
from twin.campaign.plan.formation import sight_margins
from twin.envs.episode import LEG, VISIT, EpisodePlanner, calibrated_since_moved, visit_mask
from twin.envs.moves import MoveLayout
from twin.envs.site_stations import START, Station
from twin.envs.stand_site import Stand, StandSite, TableLeg
from twin.envs.stand_tables import site_for
from twin.scenario.schema import Scenario

__all__ = ["STD_STEP", "StandPlanner", "rounded_std"]

STD_STEP = 0.025
"""The parent's horizontal standard deviation is rounded up to a multiple of this, m,
before it sets a formation's sight margins (so that legs are found once and read back)."""


def rounded_std(parent_covariance: NDArray[np.float64]) -> float:
    """The parent's horizontal standard deviation along its most uncertain axis from its
    (4, 4) covariance (yaw, x, y, z), rounded up to :data:`STD_STEP`, m (0 where it is not
    finite: a trial lost)."""
    block = np.asarray(parent_covariance, dtype=float)[1:3, 1:3]
    if not np.isfinite(block).all():
        return 0.0
    std = math.sqrt(max(float(np.linalg.eigvalsh(block).max()), 0.0))
    return STD_STEP * math.ceil(std / STD_STEP - 1e-9)


@dataclass
class StandPlanner(EpisodePlanner):
    """An episode's campaign on a site's table, advanced by an agent's moves (see the
    module and :class:`twin.envs.episode.EpisodePlanner`).

    Args:
        scenario: the site. layout: the moves. budget_m: the parent's travel allowed, m.

    Attributes:
        parent_std: gives the trial's parent covariance's rounded standard deviation
            (:func:`rounded_std`) when a leg's moves are weighed; the environment sets it.
    """

    scenario: Scenario
    layout: MoveLayout
    budget_m: float
    parent_std: Callable[[], float] = field(default=lambda: 0.0)

    def __post_init__(self) -> None:
        self.site = site_for(self.scenario, self.layout)
        self.stations: dict[str, Station] = self.site.stations
        self.order = self.site.order
        self._stand = self.site.at[START]
        self._pending = self.site.start
        self.decision: str | None = VISIT
        self.time = self.site.start_time
        self.travelled = 0.0
        self.visits: dict[str, int] = {}
        self.calibrated_at: dict[str, float] = {}  # the parent's travel at each one's last, m
        self._goal: str | None = None
        self._travel: list[Stand] = []
        self._direction = 1.0
        self._where = {name: xy.copy() for name, xy in self.site.ready_xy.items()}
        self._mask: NDArray[np.bool_] | None = None
        self._legs: list[TableLeg | None] = []
        self.computed = 0

    # -- where the campaign stands ----------------------------------------------------------
    @property
    def memo(self) -> StandSite:
        """The site's table (planners of one site in one process share it)."""
        return self.site

    @property
    def mask(self) -> NDArray[np.bool_]:
        """(n,) the moves allowed now (read-only)."""
        if self._mask is None:
            self._mask = self._allowed()
            self._mask.flags.writeable = False
        return self._mask

    def here(self) -> str | None:
        """The station the parent stands at (the nearest within reach), or None."""
        return self.site.station_at(self._stand)

    @property
    def goal_station(self) -> Station | None:
        """The station the group travels to, during a travel."""
        return None if self._goal is None else self.stations[self._goal]

    def route_distance(self, station: Station) -> float:
        """The parent's travel along the route to a station, m."""
        return self.site.distances(self._stand)[station.name]

    # -- moves ------------------------------------------------------------------------------
    def _take(self, action: int) -> tuple[Step, ...]:
        layout = self.layout
        steps: tuple[Step, ...] = ()
        if action == layout.end:
            self.decision = None
        elif self.decision == LEG:
            leg = self._legs[action]
            assert leg is not None
            steps = self.site.leg_steps(leg)
            to = self._travel[min(self._cells(action), len(self._travel)) - 1]
            self.travelled += float(np.linalg.norm(to.xy - self._stand.xy))
            drives = self.site.drive_time(self._where, leg.stops.items())
            self.time += drives + self.site.leg_overhead
            self._travel = self._travel[self._travel.index(to) + 1 :]
            self._stand = to
            if not self._travel:
                self.decision, self._goal = VISIT, None
        elif action == layout.calibrate:
            here = self.here()
            assert here is not None
            camera = self.stations[here].camera
            assert camera is not None
            self.visits[camera] = self.visits.get(camera, 0) + 1
            self.calibrated_at[camera] = self.travelled
            steps = self.site.data_steps(here, self.visits[camera])
            data = self.site.station_data(here)
            assert data is not None
            self.time += data.time
            self._where.update({r: xy.copy() for r, xy in data.stops.items()})
        else:
            name = START if action == layout.return_start else self.order[action - layout.go_to(0)]
            self._travel, self._direction = self.site.travel(self._stand, name)
            self._goal, self.decision = name, LEG
            if float(np.linalg.norm(self.site.at[name].xy - self._stand.xy)) < ARRIVED:
                self._stand, self._travel = self.site.at[name], []  # there already
                self.decision, self._goal = VISIT, None
        self._mask = None
        self.computed += 1
        return steps

    def _cells(self, action: int) -> int:
        return self.site.cells[self.layout.leg_of(action)[1]]

    def _allowed(self) -> NDArray[np.bool_]:
        layout = self.layout
        mask = np.zeros(layout.size, dtype=bool)
        if self.decision == LEG:
            assert self._goal is not None
            margins = sight_margins(self.parent_std())
            goal = self.stations[self._goal]
            back = 0.0 if self._direction > 0 else math.pi
            ends = []
            for factor in layout.step_factors:
                to = self._travel[min(self.site.cells[factor], len(self._travel)) - 1]
                heading = goal.yaw if to.station else self.site.heading(to) + back
                ends.append((to, heading))
            self._legs = [
                self.site.leg(self._stand, to, self._direction, name, margins, heading)
                for name in layout.formations
                for to, heading in ends
            ]
            mask[: layout.legs] = [leg is not None for leg in self._legs]
            if not mask.any():
                mask[layout.end] = True  # no room for any formation: the campaign ends
        elif self.decision == VISIT:
            here = self.here()
            camera = None if here is None else self.stations[here].camera
            visit_mask(
                mask,
                layout,
                self.order,
                here,
                here is not None
                and camera is not None
                and self.site.station_data(here) is not None
                and not calibrated_since_moved(self.calibrated_at, camera, self.travelled),
                self.site.distances(self._stand).__getitem__,
                self.budget_m - self.travelled,
            )
        return mask

    def close(self) -> None:
        """Nothing to free: the site's table is the process's."""
