"""How long the campaign's loops may go on before the campaign counts as stuck.

A campaign that cannot progress (a travel whose legs never reach the station, a data set
whose stops never give points, a strategy that keeps asking for travels) must end, and say
where it was stuck. Every loop of the campaign has a bound computed from the scenario
(:func:`campaign_bounds`); a loop that reaches its bound ends with the failure
``no_progress`` (:data:`NO_PROGRESS`), whose message names the stage, where the parent
stands, the count and the bound (:class:`twin.campaign.travel.NoProgress`):

- :attr:`CampaignBounds.legs`: CPS legs of one travel (to a visit's station, or back);
  reaching it aborts the campaign.
- :attr:`CampaignBounds.travels`: travels (visits and returns) of the whole campaign;
  reaching it aborts the campaign.
- :attr:`CampaignBounds.stops`: a child's stops for one data set; reaching it ends the data
  set with the points it has (the campaign goes on).
- :attr:`CampaignBounds.recoveries`: legs in a row that failed and were backed off from
  (:mod:`twin.campaign.recovery`); reaching it aborts the campaign.
- :attr:`CampaignBounds.drives`: drives of all the robots in the whole campaign; what the
  other bounds allow, counted drive by drive (:func:`drives_bound`), so that a loop inside
  a leg or a stop that went on would end too; reaching it aborts the campaign.

The retries inside one measurement (further aims after a lost lock, the prism search, the
re-aims from the prisms found, a second try after inconsistent shots) are loops of fixed
length: :func:`aims_bound` counts them. They end with their own failures
(``shot_given_up``, ``prism_missing``, ``inconsistent_marker``) and the campaign goes on.

The bounds scale with ``campaign.progress_slack`` (default 2): how many times what a
campaign that progresses needs its loops may take.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from twin.campaign.aborted import NO_PROGRESS, NoProgress
from twin.campaign.drives import LONG_DRIVE_M, TRACK_STEP_M
from twin.campaign.paper_strategy import SHORTEST_LEG, halvings
from twin.campaign.parent_fix import SIDESTEPS
from twin.campaign.shooting import SEARCH_DEG
from twin.campaign.travel import TURNS_DEG
from twin.scenario.schema import Scenario

__all__ = [
    "NO_PROGRESS",
    "CampaignBounds",
    "NoProgress",
    "aims_bound",
    "campaign_bounds",
    "drives_bound",
    "legs_bound",
    "recoveries_bound",
    "stops_bound",
    "travels_bound",
]

SHORTEST_LEG_FRACTION = SHORTEST_LEG / 2
"""The shortest leg a travel is planned in, as a fraction of ``campaign.formation.step``
(0.15): the paper's strategy halves a leg where the children have no room, down to legs of
:data:`twin.campaign.paper_strategy.SHORTEST_LEG` (0.3) of a step, so the legs it takes are
longer than half that (save a travel's single leg, shorter than a step)."""

REAIM_ROUNDS = 3
"""Rounds of re-aims from the prisms found (:func:`twin.campaign.shooting.shoot_cubes`)."""

REAIMS_PER_ROUND = 6
"""Most shots of one round of re-aims: one prism found, each of the three guesses of which
cube it is aims at the two others."""

MEASURE_TRIES = 2
"""Tries at a child's three prisms (:func:`twin.campaign.shooting.measure_child`): a
second one after shots that do not fit the assembly."""


@dataclass(frozen=True)
class CampaignBounds:
    """The most each loop of a campaign may take (see the module).

    Attributes:
        legs: CPS legs of one travel. travels: travels of the campaign (visits and
            returns). stops: a child's stops for one data set. drives: drives of all the
            robots (each ``drive_to`` of a base) in the whole campaign. recoveries: legs
            in a row backed off from (:func:`recoveries_bound`).
    """

    legs: int
    travels: int
    stops: int
    drives: int
    recoveries: int = 3


def legs_bound(route_length: float, step: float, slack: float) -> int:
    """CPS legs one travel may take: ``ceil(slack * route_length / (SHORTEST_LEG_FRACTION
    * step)) + 1``.

    A travel goes along the route, at most its whole length, in legs longer than
    :data:`SHORTEST_LEG_FRACTION` of a step, and ends with at most one leg off the route
    to its station; ``slack`` times that allows for legs that stop short.

    Args:
        route_length: the route's length, m (>= 0). step: ``campaign.formation.step``, m
            (> 0). slack: ``campaign.progress_slack`` (>= 1).
    """
    return math.ceil(slack * route_length / (SHORTEST_LEG_FRACTION * step)) + 1


def recoveries_bound(slack: float) -> int:
    """Legs in a row that may fail and be backed off from: ``ceil(slack * (halvings + 1) /
    2)``, with ``halvings`` how often a step is halved down to the shortest leg
    (:data:`twin.campaign.paper_strategy.SHORTEST_LEG`): each recovery plans the leg half
    as long, so a leg the shortest cannot make is given up after ``halvings + 1`` tries at
    the default slack of 2 (3).

    Args:
        slack: ``campaign.progress_slack`` (>= 1).
    """
    return math.ceil(slack * (halvings(1.0, SHORTEST_LEG) + 1) / 2)


def travels_bound(visits: int, slack: float) -> int:
    """Travels one campaign may take: ``ceil(slack * 2 * (visits + 1))``.

    The paper's strategy takes one travel per visit and one back to the start; a strategy
    that goes to each station and then calibrates there asks twice as many (a return, then
    a visit where it stands).

    Args:
        visits: the scenario's ``calibration.visits``. slack: ``campaign.progress_slack``.
    """
    return math.ceil(slack * 2 * (visits + 1))


def stops_bound(points: int, slack: float) -> int:
    """A child's stops for one data set of ``points`` LED points: ``ceil(slack * points)``.

    A stop that gives a point gives at least one LED point, so ``points`` such stops fill
    the data set; ``slack`` times that allows for stops that give none.
    """
    return math.ceil(slack * points)


def drive_pieces(diagonal: float) -> int:
    """Drives a child's straight drive may be cut into (it is tracked, in pieces of
    :data:`twin.campaign.travel.TRACK_STEP_M`, when longer than
    :data:`~twin.campaign.travel.LONG_DRIVE_M`), for a space whose floor's diagonal is
    ``diagonal`` m: no straight drive is longer."""
    return math.ceil(diagonal / TRACK_STEP_M) if diagonal > LONG_DRIVE_M else 1


def leg_drives(children: int, corners: int, pieces: int) -> int:
    """Most drives of one CPS leg (:meth:`twin.campaign.travel.Travel.execute`).

    A move along the route is a drive back onto it, one per corner, one to the route
    abreast of the stop and one to the stop: ``corners + 3`` drives of up to ``pieces``
    each. A child makes its move, turns (:data:`~twin.campaign.travel.TURNS_DEG`), and
    once more: drives back to its last stand, moves again, turns again. The parent makes
    its move and steps aside (:data:`~twin.campaign.travel.SIDESTEPS`).

    Args:
        children: the robots' children. corners: the route's waypoints.
        pieces: :func:`drive_pieces`.
    """
    move = (corners + 3) * pieces
    child = 2 * (move + len(TURNS_DEG)) + pieces
    return children * child + move + len(SIDESTEPS)


def stop_drives(pieces: int) -> int:
    """Most drives of a child's stop for a camera's data: a way with one corner, then the
    turns to show its prisms (:meth:`twin.campaign.drives.Drives.drive_clear`,
    :meth:`~twin.campaign.travel.Travel.place_child_turning`)."""
    return 2 * pieces + len(TURNS_DEG)


def drives_bound(
    travels: int,
    legs: int,
    stops: int,
    data_sets: int,
    per_leg: int,
    per_stop: int,
) -> int:
    """Drives one campaign may take: ``travels * legs * per_leg + data_sets * stops *
    per_stop`` (the travels' legs, then the data sets' stops: the reference sets and one
    per travel)."""
    return travels * legs * per_leg + data_sets * stops * per_stop


def aims_bound(lock_retries: int) -> int:
    """Most aims of the instrument for one measurement of a child
    (:func:`twin.campaign.shooting.measure_child`): for each try, ``lock_retries + 1``
    at each of the three cubes, the prism search
    (:data:`twin.campaign.shooting.SEARCH_DEG`) and the re-aims (:data:`REAIM_ROUNDS`
    of at most :data:`REAIMS_PER_ROUND`)."""
    per_try = 3 * (lock_retries + 1) + len(SEARCH_DEG) + REAIM_ROUNDS * REAIMS_PER_ROUND
    return MEASURE_TRIES * per_try


def campaign_bounds(scenario: Scenario) -> CampaignBounds:
    """The bounds of a scenario's campaign (see the module and each ``*_bound``).

    Args:
        scenario: the plan: its route, visits, cameras, space and ``campaign`` settings.
    """
    settings = scenario.campaign
    slack = settings.progress_slack
    route = scenario.route
    legs = legs_bound(route.length, settings.formation.step, slack)
    travels = travels_bound(len(scenario.calibration.visits), slack)
    points = max(settings.reference_points, settings.station_points)
    stops = stops_bound(points, slack)
    width, depth = scenario.space.size[:2]
    pieces = drive_pieces(math.hypot(width, depth))
    per_leg = leg_drives(len(scenario.robots.children), len(route.waypoints), pieces)
    data_sets = len(scenario.cameras) + travels
    drives = drives_bound(travels, legs, stops, data_sets, per_leg, stop_drives(pieces))
    return CampaignBounds(legs, travels, stops, drives, recoveries_bound(slack))
