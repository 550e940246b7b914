"""The paper's strategy (Section IV): the scenario's route and visits in order, the group
leapfrogging along the route in equal legs with the children staggered ahead of the
parent, and a child's data at stops spread over each camera's view.

- reference data sets: the cameras named by ``campaign.reference_cameras``, else every
  camera whose floor view the first station sees (``calibration.min_visible_fraction``);
- visits: ``calibration.visits``, in order;
- legs: along the route in equal steps of at most ``campaign.formation.step``; the
  children stand ahead of the parent's next station (:func:`twin.campaign.plan.formation.
  formation`), the one farther ahead moving first (a child beside the way out of a dead
  end is on the way out, not the way in); where there is no room for them, a
  leg half as long, down to 30 % of a step; after a leg that failed and was backed off
  from (:mod:`twin.campaign.recovery`), a leg to half way first;
- data: the child nearer the camera's view takes it at the first stops of
  :func:`twin.campaign.plan.view_stops.view_stops`, in a nearest-neighbour tour, the
  later ones spare (the other child where the nearer has no way to the first stops past
  it and it has one: it stands in a doorway the stops lie beyond); at each stop it turns
  where its own assembly would hide a prism.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from calib.camera import TsaiCamera
from twin.campaign.plan.accurate_stops import choose_stops, partial_view_stops
from twin.campaign.plan.clearance import CHILD_BODY, PARENT_BODY
from twin.campaign.plan.formation import corner_formation, formation, sight_margins
from twin.campaign.plan.legs import leg_goals
from twin.campaign.plan.occlusion import unhidden_yaw
from twin.campaign.plan.route import RoutePath
from twin.campaign.plan.view_stops import tour, view_stops
from twin.campaign.plan.ways import ROBOT_MARGIN, way_to
from twin.campaign.strategy import (
    CampaignView,
    Leg,
    Move,
    NoLeg,
    Return,
    Stop,
    StopPlan,
    Strategy,
    Visit,
)
from twin.scenario.geometry import floor_view
from twin.scenario.robots import INSTRUMENT_HEIGHT
from twin.scenario.schema import FormationSettings
from twin.scenario.visibility import station_visibility

ARRIVED = 0.05
"""A parent this close to a station, m, is there: no leg is needed."""

SHORTEST_LEG = 0.3
"""Legs are halved for lack of room down to this fraction of a step."""


def halvings(length: float, shortest: float) -> int:
    """How many times a leg of ``length`` m is halved before it is no longer than
    ``shortest`` m (> 0): ``ceil(log2(length / shortest))``, 0 for a leg already that
    short (or of no finite length)."""
    if not (math.isfinite(length) and length > shortest > 0):
        return 0
    return math.ceil(math.log2(length / shortest))


MAX_TURN_AT_STOP_DEG = 50.0
"""Farthest a child turns at a data stop to show its prisms, deg."""


class PaperStrategy(Strategy):
    """The paper's decisions (see the module). One instance serves one campaign."""

    name = "paper"
    accuracy_stops = False
    """Whether a camera's data stops are chosen for accuracy whatever the scenario's
    ``campaign.data_stops`` (:class:`PlannedStrategy`)."""

    def start(self, view: CampaignView) -> None:
        sc = view.scenario
        self.path = RoutePath(sc.route.waypoints)
        self.marker = sc.marker.assembly()
        # Where the group is along the route, m of arc length.
        self._arc = self.path.project(sc.robots.parent.start_xy)
        goals: list[Visit | Return] = list(_paper_visits(view))
        if sc.route.return_to_start:
            start = np.asarray(sc.robots.parent.start_xy, dtype=float)
            yaw = math.radians(sc.robots.parent.start_yaw_deg)
            goals.append(Return(start, yaw, "back to the start to close the loop"))
        self._visits = iter(goals)
        self._goal: Visit | Return | None = None  # where the current travel goes
        self._leg_ends: list[float] | None = None  # the travel's remaining leg ends
        self._reached_s: float | None = None  # the last leg's end, to place the group by
        self._direction = 1.0

    # -- reference data sets ------------------------------------------------------------------
    def reference_cameras(self, view: CampaignView) -> list[str]:
        sc = view.scenario
        if sc.campaign.reference_cameras is not None:
            return list(sc.campaign.reference_cameras)
        start = sc.robots.parent.start_xy
        need = sc.calibration.min_visible_fraction
        prism_height = float(np.mean([c[2] for c in sc.marker.cubes]))
        return [
            c.name
            for c in sc.cameras
            if station_visibility(
                sc.space,
                c.tsai(),
                start,
                sc.space.floor_z + INSTRUMENT_HEIGHT,
                prism_height,
                view.instrument_range,
            )
            >= need
        ]

    # -- visits ---------------------------------------------------------------------------------
    def next_visit(self, view: CampaignView) -> Visit | Return | None:
        return next(self._visits, None)

    # -- legs -------------------------------------------------------------------------------------
    def next_leg(self, view: CampaignView, goal: Visit | Return) -> Leg | NoLeg | None:
        path = self.path
        parent_xy = view.parent.translation[:2]
        if goal is not self._goal:  # a new travel
            self._goal, self._leg_ends = goal, None
        self._follow_parent(parent_xy)
        if self._leg_ends is None:
            s_now = path.project(parent_xy, near=self._arc)
            if np.linalg.norm(goal.station - parent_xy) < ARRIVED:
                return None
            # A return to the start goes to the route's end (which is also its beginning).
            end = np.asarray(view.scenario.route.waypoints[-1], dtype=float)
            if isinstance(goal, Return) and np.linalg.norm(goal.station - end) < ROUTE_END:
                s_goal = path.length
            else:
                s_goal = path.project(goal.station)
            self._direction = 1.0 if s_goal >= s_now else -1.0
            self._leg_ends = leg_goals(path, s_now, s_goal, self._step(view))
        else:
            s_now = self._arc
        if not self._leg_ends:
            self._leg_ends = None
            return None
        direction, step = self._direction, self._step(view)
        form = view.scenario.campaign.formation
        s_next = self._leg_ends[0]
        margins = sight_margins(view.parent.horizontal_std)
        legs: dict[float, tuple[int, Leg] | None] = {}  # by s_next: the widest margin kept
        # The widest margin first, with legs shortened for it (a corner is turned in more
        # legs); the nominal one where nothing else fits.
        for k in range(len(margins)):
            ends = list(self._leg_ends)
            # The leg, then each half down to the shortest (one more try for rounding).
            for _ in range(halvings(abs(ends[0] - s_now), SHORTEST_LEG * step) + 2):
                s_next = ends[0]
                if s_next not in legs:
                    legs[s_next] = self.leg_between(
                        view, goal, s_now, s_next, len(ends) == 1, direction, form, margins
                    )
                found = legs[s_next]
                # A leg keeping a wider margin was taken at an earlier k.
                if found is not None and found[0] == k:
                    ends.pop(0)
                    self._leg_ends, self._reached_s = ends, s_next
                    return found[1]
                # No room for the children ahead: a shorter leg (down to a fraction of a step).
                if abs(s_next - s_now) <= SHORTEST_LEG * step:
                    break
                ends.insert(0, 0.5 * (s_now + s_next))
        corner = self._around_corner(view, goal, s_now, direction, margins)
        if corner is not None:
            return corner
        self._leg_ends = None  # s_next: the shortest leg tried with the nominal margin
        return NoLeg(
            "no_formation",
            f"no place for the children ahead of s = {s_next:.1f} m",
            f"no formation for the leg to s = {s_next:.1f} m",
        )

    def leg_failed(self, view: CampaignView, goal: Visit | Return, leg: Leg) -> None:
        """The group backed off to where the failed leg started: the leg is planned again
        to half way first (down to the shortest, :data:`SHORTEST_LEG` of a step), then on
        to where it went."""
        s_failed, self._reached_s = self._reached_s, None  # the group is still at _arc
        if s_failed is None or goal is not self._goal:
            return
        ends = list(self._leg_ends or [])
        if not ends or ends[0] != s_failed:
            ends.insert(0, s_failed)
        half = 0.5 * (self._arc + s_failed)
        if abs(half - self._arc) > 0.5 * SHORTEST_LEG * self._step(view):
            ends.insert(0, half)
        self._leg_ends = ends

    def _around_corner(
        self,
        view: CampaignView,
        goal: Visit | Return,
        s_now: float,
        direction: float,
        margins: tuple[float, ...],
    ) -> Leg | None:
        """Where the staggered formation has no room ahead of any leg's end (around a turn
        its places lie round the corner, hidden from where the parent stands), a leg with
        the children anywhere both stations see (:func:`twin.campaign.plan.formation.
        corner_formation`): to the planned leg's end, then to each of the route's corners
        before it (the parent on a corner sees along both of its legs), farthest first,
        then to shorter legs. None where none is found."""
        assert self._leg_ends is not None
        ends = list(self._leg_ends)
        s_end, step = ends[0], self._step(view)
        lo, hi = sorted((s_now, s_end))
        corners = [float(s) for s in self.path.starts[1:-1] if lo + ARRIVED < s < hi - ARRIVED]
        candidates = [s_end, *sorted(corners, key=lambda s: -direction * s)]
        for k in range(1, halvings(abs(s_end - s_now), SHORTEST_LEG * step) + 1):
            candidates.append(s_now + (s_end - s_now) / 2**k)
        form = view.scenario.campaign.formation
        for s_next in candidates:
            arrives = s_next == s_end and len(ends) == 1
            found = self.leg_between(
                view, goal, s_now, s_next, arrives, direction, form, margins, corner=True
            )
            if found is not None:
                self._leg_ends = ends[1:] if s_next == s_end else ends
                self._reached_s = s_next
                return found[1]
        return None

    @property
    def arc(self) -> float:
        """The group's arc length on the route, m: where the parent stood at its last fix
        after a leg (the start's before the first)."""
        return self._arc

    def _follow_parent(self, parent_xy: NDArray[np.float64]) -> None:
        """After a leg the parent fixed its pose: the group is where it stands (``_arc``)."""
        if self._reached_s is not None:
            self._arc = self.path.project(parent_xy, near=self._reached_s)
            self._reached_s = None

    def leg_between(
        self,
        view: CampaignView,
        goal: Visit | Return,
        s_now: float,
        s_next: float,
        arrives: bool,
        direction: float,
        form: FormationSettings,
        margins: tuple[float, ...] | None = None,
        corner: bool = False,
    ) -> tuple[int, Leg] | None:
        """The leg from arc length ``s_now`` to ``s_next`` (the goal's station if
        ``arrives``) with the children in formation ``form``, or None where they have no
        room; with the index in ``margins`` of the sight margin its formation keeps
        (``margins``: tried in turn, m; default
        :func:`twin.campaign.plan.formation.sight_margins` of the parent's estimate).
        Changes nothing: the caller that takes the leg sets ``_reached_s``."""
        if margins is None:
            margins = sight_margins(view.parent.horizontal_std)
        path = self.path
        parent_xy = view.parent.translation[:2]
        next_xy = goal.station if arrives else path.at(s_next)
        order = self._children_in_order(view, direction)
        if corner:
            found = corner_formation(
                view.scenario.space,
                self.marker.cubes_body,
                view.instrument_range,
                path,
                s_next,
                [parent_xy, *path.vertices_between(s_now, s_next), next_xy],
                direction,
                float(view.parent.translation[2]),
                view.robot_pose(order[1])[:2],
                margins,
            )
        else:
            found = formation(
                view.scenario.space,
                self.marker.cubes_body,
                view.instrument_range,
                path,
                s_next,
                parent_xy,
                next_xy,
                direction,
                form,
                float(view.parent.translation[2]),
                view.robot_pose(order[1])[:2],
                margins,
            )
        if found is None:
            return None
        kept, stops = found
        s_children = {c: self._child_arc(view.robot_pose(c)[:2], direction) for c in order}
        moves = tuple(
            self._move(child, s_children[child], path.project(stop.xy, near=self._arc), stop)
            for child, stop in zip(order, stops, strict=True)
        )
        heading = goal.yaw if arrives else path.heading(s_next) + (0 if direction > 0 else math.pi)
        parent = self._move(view.parent_name, s_now, s_next, Stop(next_xy, heading))
        return kept, Leg(moves, parent, arrives)

    def _step(self, view: CampaignView) -> float:
        return view.scenario.campaign.formation.step

    def _children_in_order(self, view: CampaignView, direction: float) -> list[str]:
        """The first two children, the one farthest ahead along the route first (it moves
        first)."""
        s = {c: self._child_arc(view.robot_pose(c)[:2], direction) for c in view.children[:2]}
        return sorted(s, key=lambda c: direction * s[c], reverse=True)

    def _child_arc(self, xy: NDArray[np.float64], direction: float) -> float:
        """A child's arc length on the route, m, from where it stands (``xy``, (2,) m): the
        nearest point of the route near the group's; where that is behind the group
        (``direction``: +1 along the route, -1 back) but the route ahead passes within
        :data:`AHEAD_TOLERANCE` as near, the point ahead. A child beside the way out of a
        dead end stands nearest the way in: placed there, it drove in past the parent."""
        path, s_now = self.path, self._arc
        s = path.project(xy, near=s_now)
        if direction * (s - s_now) >= 0:
            return s
        half = 0.5 * AHEAD_WINDOW
        ahead = path.project(xy, near=s_now + direction * half, window=half)
        if (
            direction * (ahead - s_now) > 0
            and np.linalg.norm(path.at(ahead) - xy)
            <= np.linalg.norm(path.at(s) - xy) + AHEAD_TOLERANCE
        ):
            return ahead
        return s

    def _move(self, robot: str, s_from: float, s_to: float, stop: Stop) -> Move:
        """A drive along the route from arc length ``s_from`` to ``s_to``, then to ``stop``."""
        return Move(
            robot,
            stop,
            tuple(self.path.vertices_between(s_from, s_to)),
            self.path.at(s_from),
            self.path.at(s_to),
        )

    # -- a camera's data ---------------------------------------------------------------------------
    def data_stops(self, view: CampaignView, camera: str, dataset: str, points: int) -> StopPlan:
        sc = view.scenario
        cam = sc.camera(camera).tsai()
        child = _nearest_child(view, cam.position[:2], floor_view(cam, sc.space.floor_z, 40.0, 12))
        anchor = next(c for c in view.children if c != child)
        plan = self._stops_for(view, child, anchor, cam, points)
        # The other child standing in the way (a doorway the stops lie beyond): it takes
        # the data where it has a way to them.
        if _no_way(view, child, anchor, plan) and not _no_way(view, anchor, child, plan):
            swapped = self._stops_for(view, anchor, child, cam, points)
            if not _no_way(view, anchor, child, swapped):
                return swapped
        return plan

    def _stops_for(
        self, view: CampaignView, child: str, anchor: str, cam: TsaiCamera, points: int
    ) -> StopPlan:
        """The stops of ``child`` for ``cam``'s data, ``anchor`` standing where it is."""
        sc = view.scenario
        if self.accuracy_stops or sc.campaign.data_stops == "accuracy":
            return self._accurate_stops(view, child, anchor, cam, points)
        parent = view.parent
        candidates = view_stops(
            sc.space,
            self.marker,
            view.instrument_range,
            cam,
            parent.translation[:2],
            float(parent.translation[2]),
            view.robot_pose(anchor)[:2],
        )
        need = math.ceil(points / view.led_count)
        if not candidates:
            return StopPlan(child, [])
        planned = tour(candidates[:need], view.robot_pose(child)[:2])
        eye = parent.translation.copy()
        return StopPlan(
            child,
            [v.stop for v in planned],
            [v.stop for v in candidates[need:]],
            self._heading(view, eye),
        )

    def _heading(
        self, view: CampaignView, eye: NDArray[np.float64]
    ) -> Callable[[Stop], float | None]:
        """The heading at a stop at which all the child's prisms show to the instrument at
        ``eye`` (None: none does)."""
        marker, floor = self.marker, view.scenario.space.floor_z

        def heading(stop: Stop) -> float | None:
            # Turn the child where its own mast, arms or prisms would hide a prism.
            return unhidden_yaw(
                stop.xy, stop.yaw, marker.cubes_body, eye, floor, MAX_TURN_AT_STOP_DEG
            )

        return heading

    def _accurate_stops(
        self, view: CampaignView, child: str, anchor: str, cam: TsaiCamera, points: int
    ) -> StopPlan:
        """``campaign.data_stops = "accuracy"``: the stops of
        :func:`twin.campaign.plan.accurate_stops.choose_stops` among the places that show
        at least one LED, the planned ones in a nearest-neighbour tour."""
        sc, parent = view.scenario, view.parent
        candidates = partial_view_stops(
            sc.space,
            self.marker,
            view.instrument_range,
            cam,
            parent.translation[:2],
            float(parent.translation[2]),
            view.robot_pose(anchor)[:2],
        )
        if not candidates:
            return StopPlan(child, [], partial=True)
        eye = parent.translation.copy()
        planned, spares = choose_stops(candidates, cam, eye, view.instrument, points)
        planned = tour(planned, view.robot_pose(child)[:2])
        return StopPlan(
            child,
            [v.stop for v in planned],
            [v.stop for v in spares],
            self._heading(view, eye),
            partial=True,
        )


AHEAD_TOLERANCE = 1.0
"""A child nearest the route behind the group is placed on the route ahead where that
passes at most this much farther from it, m (:meth:`PaperStrategy._child_arc`)."""

AHEAD_WINDOW = 10.0
"""How far ahead of the group along the route a child's place is searched, m."""

ROUTE_END = 0.5
"""A return to a place this close to the route's end (m) goes to the end of the route."""


def _paper_visits(view: CampaignView) -> list[Visit]:
    """The scenario's visits, numbered per camera."""
    out: list[Visit] = []
    seen: dict[str, int] = {}
    for v in view.scenario.calibration.visits:
        seen[v.camera] = seen.get(v.camera, 0) + 1
        station = np.asarray(v.station, dtype=float)
        out.append(Visit(v.camera, seen[v.camera], station, math.radians(v.yaw_deg)))
    return out


WAY_STOPS = 3
"""How many of a camera's first planned stops a child with no way to is blocked."""


def _no_way(view: CampaignView, child: str, other: str, plan: StopPlan) -> bool:
    """Whether ``child`` has no way (:func:`twin.campaign.plan.ways.way_to`) clear of the
    parent and ``other`` standing to any of ``plan``'s first :data:`WAY_STOPS` stops (False
    for a plan with none)."""
    stops = plan.upcoming[:WAY_STOPS]
    robots = np.array([view.parent.translation[:2], view.robot_pose(other)[:2]])
    keep = np.array([PARENT_BODY + CHILD_BODY + ROBOT_MARGIN, 2 * CHILD_BODY + ROBOT_MARGIN])
    here = view.robot_pose(child)[:2]
    space = view.scenario.space
    return bool(stops) and all(way_to(space, here, s.xy, robots, keep) is None for s in stops)


def _nearest_child(
    view: CampaignView, camera_xy: NDArray[np.float64], ground: NDArray[np.float64]
) -> str:
    """The child nearest the middle of a camera's view of the floor (of the camera itself
    when it sees no floor)."""
    centre = ground[:, :2].mean(axis=0) if len(ground) else camera_xy
    return min(view.children, key=lambda c: float(np.linalg.norm(view.robot_pose(c)[:2] - centre)))


class PlannedStrategy(PaperStrategy):
    """The paper's visits and CPS legs, with each camera's data stops chosen for accuracy
    (whatever ``campaign.data_stops`` says): wherever at least one LED shows, greedily to
    lower the predicted covariance of the camera's position
    (:mod:`twin.campaign.plan.accurate_stops`). The default strategy: on the paper's hall
    it takes the cameras' world-frame position errors from 22 / 33 / 19 / 35 / 39 mm RMS
    (the paper's stops) to 3.6 / 8.9 / 10.6 / 14.0 / 21.6 mm."""

    name = "planned"
    accuracy_stops = True
