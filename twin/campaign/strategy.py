"""The campaign's decisions, as a small interface: a :class:`Strategy` decides, the campaign
(:mod:`twin.campaign.procedure`) executes through :mod:`twin.hal`.

The decisions:

- :meth:`Strategy.reference_cameras`: which cameras get a reference data set from the
  first station;
- :meth:`Strategy.next_visit`: the next camera to calibrate and its station
  (:class:`Visit`), a place to return to (:class:`Return`), or the end;
- :meth:`Strategy.next_leg`: the next CPS leg towards it (:class:`Leg`: where each child
  stops, in which order, and where the parent goes: the formation and the step length),
  None once there, or :class:`NoLeg`; :meth:`Strategy.leg_failed`: a leg failed and the
  group backed off, the next one is to be shorter;
- :meth:`Strategy.data_stops`: where a child stops for a camera's data (:class:`StopPlan`).

A strategy sees what the campaign knows (:class:`CampaignView`: the map, the CPS estimate
and its covariance, the robots' own pose estimates, what is calibrated, the instrument's
specification as the interface reports it) and nothing of a backend: this module and the
strategies import no device.

The campaign asks its questions one at a time (:class:`Question`): :meth:`Campaign.run
<twin.campaign.procedure.Campaign.run>` answers each with its strategy, while a caller
that drives :meth:`Campaign.steps <twin.campaign.procedure.Campaign.steps>` itself (an
environment whose agent decides) answers them as it likes, decision by decision.
"""

from __future__ import annotations

import abc
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from twin.campaign.plan.stop import Stop
from twin.campaign.records import CalibrationRecord
from twin.instruments.total_station import TotalStationSpec
from twin.localization.pose import ParentPose
from twin.scenario.schema import Scenario

__all__ = [
    "CampaignView",
    "DataStops",
    "Leg",
    "Move",
    "NextLeg",
    "NextVisit",
    "NoLeg",
    "PlannedStop",
    "Question",
    "ReferenceCameras",
    "Return",
    "Stop",
    "StopPlan",
    "Strategy",
    "Visit",
]


# -- what a strategy sees ----------------------------------------------------------------------
class CampaignView(abc.ABC):
    """What the campaign knows, read-only, for its strategy.

    The scenario is the plan and the map (the space, the cameras' nominal poses, the route,
    the visits, the marker as surveyed, the campaign's settings); its simulated noise and
    faults belong to the twin, and a strategy does not read them: what the campaign knows of
    its devices comes from the interface (:attr:`instrument`).
    """

    @property
    @abc.abstractmethod
    def scenario(self) -> Scenario:
        """The plan and the map."""

    @property
    @abc.abstractmethod
    def instrument(self) -> TotalStationSpec:
        """The total station's specification, as the instrument reports it."""

    @property
    def instrument_range(self) -> tuple[float, float]:
        """The total station's (least, greatest) distance, m."""
        spec = self.instrument
        return (spec.range_min, spec.range_max)

    @property
    @abc.abstractmethod
    def parent_name(self) -> str:
        """The parent's name."""

    @property
    @abc.abstractmethod
    def children(self) -> tuple[str, ...]:
        """The children's names, in the rig's order."""

    @property
    @abc.abstractmethod
    def led_count(self) -> int:
        """LEDs on each child's marker."""

    @property
    @abc.abstractmethod
    def parent(self) -> ParentPose:
        """The parent's CPS estimate: yaw, instrument centre in W and their covariance."""

    @abc.abstractmethod
    def child_position(self, child: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """A child's CPS estimate: (3,) reference point in W, m, and its (3, 3) covariance."""

    @abc.abstractmethod
    def robot_pose(self, robot: str) -> NDArray[np.float64]:
        """(3,) a robot's own estimate of its pose (x m, y m, yaw rad) in W."""

    @property
    @abc.abstractmethod
    def calibrations(self) -> tuple[CalibrationRecord, ...]:
        """The calibrations made so far, in order."""


# -- the decisions ------------------------------------------------------------------------------
@dataclass(frozen=True)
class Visit:
    """Calibrate a camera from a station.

    Attributes:
        camera: the camera's name. number: the camera's visit number, 1 for the first.
        station: (2,) where the parent stands, m in W. yaw: its heading there, rad.
    """

    camera: str
    number: int
    station: NDArray[np.float64]
    yaw: float


@dataclass(frozen=True)
class Return:
    """Go back to a place without calibrating there (e.g. to the start, to close the loop).

    Attributes:
        station: (2,) where the parent goes, m in W. yaw: its heading there, rad.
        reason: words, for the records.
    """

    station: NDArray[np.float64]
    yaw: float
    reason: str = ""


@dataclass(frozen=True)
class Move:
    """A robot's drive to a stop along the route.

    The robot passes the route's ``corners`` in order, then drives to ``stop``. If it
    cannot drive straight to the first corner it first rejoins the route at ``entry``;
    if the stop is not in plain reach of the last corner it goes through ``on_route``,
    the route's point abreast of the stop.

    Attributes:
        robot: the robot's name. stop: where it stops.
        corners: (2,) points, m. entry, on_route: (2,) points, m.
    """

    robot: str
    stop: Stop
    corners: tuple[NDArray[np.float64], ...]
    entry: NDArray[np.float64]
    on_route: NDArray[np.float64]


@dataclass(frozen=True)
class Leg:
    """One CPS leg: the children move to their stops one after the other (each measured
    by the standing parent), then the parent moves and fixes its pose from them.

    Attributes:
        children: the children's moves, in the order they move.
        parent: the parent's move.
        arrives: whether the parent's stop is the goal's station.
    """

    children: tuple[Move, ...]
    parent: Move
    arrives: bool


@dataclass(frozen=True)
class NoLeg:
    """No leg can be planned: the campaign records ``kind`` and ends.

    Attributes:
        kind: the failure's name (e.g. ``no_formation``). message: what was missing.
        reason: why the campaign ends, for the records.
    """

    kind: str
    message: str
    reason: str


@dataclass(frozen=True)
class PlannedStop:
    """A child's next stop for a camera's data, and the heading at which all its prisms
    show to the total station (None when no heading does)."""

    stop: Stop
    yaw: float | None


class StopPlan:
    """Where a child stops for one camera's data: the planned stops in order, and spares
    that replace the stops that gave no point.

    Args:
        child: the child that takes the data.
        planned: the stops to visit, in order.
        spares: stops that replace failed ones, in order.
        heading: the heading at a stop at which all its prisms show (None: none does);
            worked out when the stop comes (default: the stop's own heading).
        partial: a stop where the camera finds only some of the LEDs gives a point with
            those (the stops were chosen where some LEDs show); otherwise it gives none.
    """

    def __init__(
        self,
        child: str,
        planned: Sequence[Stop],
        spares: Sequence[Stop] = (),
        heading: Callable[[Stop], float | None] | None = None,
        partial: bool = False,
    ) -> None:
        self.child = child
        self.partial = partial
        self._planned = list(planned)
        self._spares = list(spares)
        self._heading = heading or (lambda stop: stop.yaw)

    @property
    def empty(self) -> bool:
        """Whether there is no stop at all, planned or spare."""
        return not self._planned and not self._spares

    def __len__(self) -> int:
        """Stops left to visit (spares not counted)."""
        return len(self._planned)

    @property
    def upcoming(self) -> tuple[Stop, ...]:
        """The stops left to visit, in order (spares not counted)."""
        return tuple(self._planned)

    def next(self) -> PlannedStop | None:
        """The next stop, or None when none is left."""
        if not self._planned:
            return None
        stop = self._planned.pop(0)
        return PlannedStop(stop, self._heading(stop))

    def replace(self) -> None:
        """The last stop gave no point: the next spare joins the end of the plan."""
        if self._spares:
            self._planned.append(self._spares.pop(0))


# -- the strategy -------------------------------------------------------------------------------
class Strategy(abc.ABC):
    """The campaign's decisions. A strategy may keep state between its answers (one
    instance serves one campaign); :meth:`start` is called once, before any question.

    Attributes:
        name: the name ``--strategy`` and ``campaign.strategy`` know it by.
    """

    name: str = ""

    def start(self, view: CampaignView) -> None:  # noqa: B027  (a hook: nothing by default)
        """The campaign starts (nothing by default)."""

    @abc.abstractmethod
    def reference_cameras(self, view: CampaignView) -> list[str]:
        """The cameras whose reference data sets are taken from the first station."""

    @abc.abstractmethod
    def next_visit(self, view: CampaignView) -> Visit | Return | None:
        """Where the group goes next: a camera to calibrate, a place to return to, or None
        when the campaign is over."""

    @abc.abstractmethod
    def next_leg(self, view: CampaignView, goal: Visit | Return) -> Leg | NoLeg | None:
        """The next CPS leg towards ``goal``'s station; None once the parent is there (it
        may stop short of it if a drive was blocked); :class:`NoLeg` if none can be made."""

    def leg_failed(self, view: CampaignView, goal: Visit | Return, leg: Leg) -> None:  # noqa: B027
        """``leg`` towards ``goal`` failed and the group backed off to a place measured
        before (:mod:`twin.campaign.recovery`): the next :meth:`next_leg` should be
        shorter. Nothing by default (the next leg is planned from where the group is)."""

    @abc.abstractmethod
    def data_stops(self, view: CampaignView, camera: str, dataset: str, points: int) -> StopPlan:
        """Where a child stops for ``camera``'s data (``dataset``: ``reference`` or
        ``visit``), for ``points`` LED points."""


# -- the questions the campaign asks ------------------------------------------------------------
class Question(abc.ABC):
    """A decision the campaign asks for: :meth:`ask` puts it to a strategy."""

    @abc.abstractmethod
    def ask(self, strategy: Strategy, view: CampaignView) -> object:
        """The strategy's answer."""


@dataclass(frozen=True)
class ReferenceCameras(Question):
    """Which cameras get a reference data set: answered with a list of names."""

    def ask(self, strategy: Strategy, view: CampaignView) -> list[str]:
        return strategy.reference_cameras(view)


@dataclass(frozen=True)
class NextVisit(Question):
    """Where next: answered with a :class:`Visit`, a :class:`Return` or None."""

    def ask(self, strategy: Strategy, view: CampaignView) -> Visit | Return | None:
        return strategy.next_visit(view)


@dataclass(frozen=True)
class NextLeg(Question):
    """The next leg towards ``goal``: a :class:`Leg`, None (there) or :class:`NoLeg`.

    ``failed``: the leg before, which failed, the group backed off (the strategy is told
    first, :meth:`Strategy.leg_failed`); None when it did not."""

    goal: Visit | Return
    failed: Leg | None = None

    def ask(self, strategy: Strategy, view: CampaignView) -> Leg | NoLeg | None:
        if self.failed is not None:
            strategy.leg_failed(view, self.goal, self.failed)
        return strategy.next_leg(view, self.goal)


@dataclass(frozen=True)
class DataStops(Question):
    """Where the child stops for ``camera``'s data: answered with a :class:`StopPlan`."""

    camera: str
    dataset: str
    points: int

    def ask(self, strategy: Strategy, view: CampaignView) -> StopPlan:
        return strategy.data_stops(view, self.camera, self.dataset, self.points)
