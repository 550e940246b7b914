"""The table of a site that the ``stands`` planner (:mod:`twin.envs.stands`) reads: computed
once per site and process (:class:`StandSite`, :func:`site_for`).

- the **stands**: where the parent can stop on a travel. Between two stations' places on
  the route, the route is cut into equal cells of at most the layout's shortest step
  (``min(step_factors)`` times ``campaign.formation.step``); a leg of step factor ``f``
  advances ``f / min(step_factors)`` cells (rounded), its last leg ends at the station.
  Each calibration station and the start is a stand of its own, where the station is;
- the **legs**: for a pair of stands, a direction, a formation and the sight margins, the
  children's stops, found as the campaign finds them (:func:`twin.campaign.plan.
  formation.formation`), with every robot's truth there from the site's world (floor tilt
  included); found the first time a leg is asked for, then read back;
- the **stations' data**: the plan's steps of each station's data set and calibration,
  recorded once from the campaign itself, run noise-free with the paper's strategy
  (:class:`twin.batch.steps.PlanSession`). Its start (the reference data) is the episode's
  start.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.batch.steps import (
    BatchPlan,
    Calibrate,
    DataSetDone,
    Drive,
    Fix,
    Place,
    PlanSession,
    Point,
    RobotTruth,
    Step,
)
from twin.campaign.paper_strategy import ARRIVED
from twin.campaign.plan.formation import formation
from twin.campaign.plan.route import RoutePath
from twin.campaign.strategy import DataStops, Leg, NextLeg, NextVisit, Visit
from twin.envs.moves import MoveLayout, formation_settings
from twin.envs.site_stations import START, site_stations
from twin.envs.stand_cache import read_table, write_table
from twin.scenario.schema import Scenario

SAVE_EVERY = 10.0
"""Seconds between two saves of a table that grows (it is also saved when the process
ends, or drops or closes it)."""


@dataclass(frozen=True)
class Stand:
    """Where the parent can stop.

    Attributes:
        index: its place in the site's list. xy: (2,) the instrument's ground point, m (W).
        arc: its arc length on the route, m. station: the station there (its own stand),
            or None on the route.
    """

    index: int
    xy: NDArray[np.float64]
    arc: float
    station: str | None = None


@dataclass
class TableLeg:
    """A leg found: each robot's drive (the children's in order, then the parent's), the
    children it fixes, each robot's stop (for the clock), and its steps once it is taken
    (:meth:`StandSite.leg_steps`: the robots' truths are probed only then).

    Attributes:
        drives: (robot, (3,) planar pose x m, y m, yaw rad in W) in order.
        fixed: the children the parent fixes at the end.
        stops: each robot's (2,) stop, m.
        steps: the plan's steps, or None before the leg is first taken.
    """

    drives: tuple[tuple[str, NDArray[np.float64]], ...]
    fixed: tuple[str, ...]
    stops: dict[str, NDArray[np.float64]]
    steps: tuple[Step, ...] | None = None


@dataclass(frozen=True)
class StationData:
    """A station's data set and calibration as the paper's run took them.

    Attributes:
        steps: the plan's steps (numbered as the paper's visit). time: how long they
            took, s.
        stops: where each robot that moved stood at the end (2,), m.
    """

    steps: tuple[Step, ...]
    time: float
    stops: dict[str, NDArray[np.float64]]


def _renumbered(step: Step, visit: int) -> Step:
    """A data step with the visit number ``visit``."""
    if isinstance(step, (Point, DataSetDone, Calibrate)):
        return replace(step, visit=visit)
    return step


class StandSite:
    """A site's table: its stands, its stations' data and the legs found so far (see the
    module).

    Args:
        scenario: the site and its campaign settings.
        layout: the moves.

    Attributes:
        plan: the campaign's plan before its first decision. start: the plan's steps of
            the start (the reference data). start_time: how long the start took, s.
        start_xy: each robot's (2,) place at the start, m (W). ready_xy: where the start's
            reference data left it, m (W): the first leg's drives start there.
        stations, order: as :class:`twin.envs.planner.CampaignPlanner`'s.
        stands: every stand. at: each station's stand, by the station's name.
        data: each station's data, by name (a station the paper's run did not calibrate at
            has none).
        leg_overhead: the shots' time of a leg, s.
    """

    def __init__(self, scenario: Scenario, layout: MoveLayout) -> None:
        self.scenario, self.layout = scenario, layout
        self.path = RoutePath(scenario.route.waypoints)
        self.stations = site_stations(scenario, self.path)
        self.order = tuple(name for name in self.stations if name != START)
        if len(self.order) > layout.max_stations:
            raise ValueError(
                f"{scenario.name}: {len(self.order)} stations, more than max_stations = "
                f"{layout.max_stations}"
            )
        base = scenario.campaign.formation
        shortest = min(layout.step_factors)
        self.cell = shortest * base.step
        self.cells = {f: max(1, round(f / shortest)) for f in layout.step_factors}
        self.forms = {name: formation_settings(name, base) for name in layout.formations}
        self.marker = scenario.marker.assembly()
        spec = scenario.noise.total_station.spec()
        self.instrument_range = (spec.range_min, spec.range_max)
        self.legs: dict[tuple[object, ...], TableLeg | None] = {}
        self._truths: dict[tuple[str, tuple[float, ...]], RobotTruth] = {}
        self._data_steps: dict[tuple[str, int], tuple[Step, ...]] = {}
        self._distances: dict[int, dict[str, float]] = {}
        self._here: dict[int, str | None] = {}
        self._headings: dict[int, float] = {}
        self._recorder: PlanSession | None = None  # the paper's run, answered as needed
        self._prober: PlanSession | None = None  # the robots' truths on the legs
        self.data: dict[str, StationData] = {}
        self._overhead: float | None = None
        self.recorded = False  # the paper's run is over: every station's data are known
        saved = read_table(scenario, layout)
        if saved is not None:
            self._restore(saved)
        else:
            self._open_recorder()
        self._saved_size = self._size() if saved is not None else -1
        self._saved_at = time.monotonic()
        self._build_stands()

    # -- the site's paper run ---------------------------------------------------------------
    def _open_recorder(self) -> None:
        """Start the paper's campaign and run its start (the reference data)."""
        session = self._recorder = PlanSession(self.scenario, "paper")
        start: list[Step] = []
        try:
            while not session.done and not isinstance(session.question, NextVisit):
                start.extend(session.answer(session.suggested()))
        except BaseException:
            session.close()
            self._recorder = None
            raise
        self.plan: BatchPlan = session.plan
        self.start = tuple(start)
        self.start_time = session.time
        robots = (self.plan.parent, *self.plan.children)
        self.speed = {name: session.max_speed(name) for name in robots}
        where = {name: self.plan.start[name].pose[:2].copy() for name in robots}
        self.start_xy = {name: xy.copy() for name, xy in where.items()}
        # The reference data moved the children: the first leg drives from their last stops.
        self.drive_time(where, ((s.robot, s.believed[:2]) for s in start if isinstance(s, Drive)))
        self.ready_xy = {name: xy.copy() for name, xy in where.items()}
        self._where = where
        self._goal: object = None

    def _record_more(self) -> bool:
        """Answer the paper's run's next question (recording a station's data, the first
        leg's overhead); False once the run is over."""
        if self.recorded:
            return False
        if self._recorder is None:
            self._open_recorder()  # a table read back before its run was over: run it again
        session = self._recorder
        assert session is not None
        if session.done:
            self.recorded = True
            session.close()
            self._recorder = None
            return False
        where = self._where
        question, answer = session.question, session.suggested()
        before, moved = session.time, where.copy()
        steps = session.answer(answer)
        driving = self.drive_time(
            where, ((s.robot, s.believed[:2]) for s in steps if isinstance(s, Drive))
        )
        if isinstance(question, NextVisit):
            self._goal = answer
        elif isinstance(question, NextLeg) and isinstance(answer, Leg):
            if self._overhead is None:
                self._overhead = session.time - before - driving
        elif isinstance(question, DataStops) and isinstance(self._goal, Visit):
            name = self._station_of(self._goal)
            if name is not None and name not in self.data and _calibrates(steps):
                stops = {r: xy for r, xy in where.items() if not np.array_equal(xy, moved[r])}
                self.data[name] = StationData(steps, session.time - before, stops)
        return True

    def station_data(self, name: str) -> StationData | None:
        """A station's data as the paper's run took them (its run is answered until it
        reaches them), or None where that run did not calibrate there."""
        while name not in self.data and self._record_more():
            pass
        return self.data.get(name)

    @property
    def leg_overhead(self) -> float:
        """The shots' time of a leg, s: the first leg of the paper's run (0 where it had
        none)."""
        while self._overhead is None and self._record_more():
            pass
        return 0.0 if self._overhead is None else self._overhead

    def drive_time(
        self,
        where: dict[str, NDArray[np.float64]],
        drives: Iterable[tuple[str, NDArray[np.float64]]],
    ) -> float:
        """The time of drives (robot, (2,) goal) in turn by the geometric clock (straight
        travel at top speed), s; ``where`` (each robot's position) follows the robots."""
        time = 0.0
        for robot, xy in drives:
            time += float(np.linalg.norm(xy - where[robot])) / self.speed[robot]
            where[robot] = np.array(xy[:2], dtype=float)
        return time

    def _station_of(self, visit: Visit) -> str | None:
        for name, st in self.stations.items():
            if (
                st.camera == visit.camera
                and np.allclose(st.xy, visit.station)
                and math.isclose(st.yaw, visit.yaw)
            ):
                return name
        return None

    # -- stands -----------------------------------------------------------------------------
    def _build_stands(self) -> None:
        keys = sorted({round(st.arc, 9) for st in self.stations.values()})
        arcs: list[float] = []
        for a, b in itertools.pairwise(keys):
            n = max(1, math.ceil((b - a) / self.cell - 1e-9))
            arcs.extend(a + (b - a) * m / n for m in range(n))
        arcs.append(keys[-1])
        stands = [Stand(i, self.path.at(s), s) for i, s in enumerate(arcs)]
        self.at: dict[str, Stand] = {}
        for name, st in self.stations.items():
            stand = Stand(len(stands), st.xy.copy(), st.arc, name)
            stands.append(stand)
            self.at[name] = stand
        self.stands = stands

    def travel(self, here: Stand, goal: str) -> tuple[list[Stand], float]:
        """The stands of a travel from ``here`` to station ``goal``'s (the route's stands
        strictly between, then the station's), and its direction (+1 or -1 along the
        route)."""
        end = self.at[goal]
        direction = 1.0 if end.arc >= here.arc else -1.0
        lo, hi = sorted((here.arc, end.arc))
        inside = [s for s in self.stands if s.station is None and lo + 1e-6 < s.arc < hi - 1e-6]
        inside.sort(key=lambda s: direction * s.arc)
        return [*inside, end], direction

    def distances(self, here: Stand) -> dict[str, float]:
        """The parent's travel along the route from ``here`` to each station, m (by name;
        worked out once per stand)."""
        found = self._distances.get(here.index)
        if found is None:
            path = self.path
            off = float(np.linalg.norm(path.at(here.arc) - here.xy))
            found = self._distances[here.index] = {
                name: abs(st.arc - here.arc) + off + float(np.linalg.norm(path.at(st.arc) - st.xy))
                for name, st in self.stations.items()
            }
        return found

    def heading(self, stand: Stand) -> float:
        """The route's heading at a stand, rad (worked out once per stand)."""
        found = self._headings.get(stand.index)
        if found is None:
            found = self._headings[stand.index] = self.path.heading(stand.arc)
        return found

    def station_at(self, here: Stand) -> str | None:
        """The station within reach of ``here`` (the nearest), or None."""
        if here.index not in self._here:
            near = {n: float(np.linalg.norm(st.xy - here.xy)) for n, st in self.stations.items()}
            name = min(near, key=near.__getitem__)
            self._here[here.index] = name if near[name] < ARRIVED else None
        return self._here[here.index]

    def children_order(self, direction: float) -> list[str]:
        """The two children, the one ahead along the route (at the start) first."""
        s = {c: self.path.project(self.start_xy[c]) for c in self.plan.children[:2]}
        return sorted(s, key=lambda c: direction * s[c], reverse=True)

    # -- legs and data ----------------------------------------------------------------------
    def truth(self, robot: str, pose: NDArray[np.float64]) -> RobotTruth:
        """Where ``robot`` truly stands at ``pose`` (read back after the first time)."""
        key = (robot, tuple(np.round(pose, 9).tolist()))
        found = self._truths.get(key)
        if found is None:
            if self._prober is None:
                # A session of its own, whose campaign never runs: every probe starts from
                # the robots at their start, whatever the paper's run has done so far.
                self._prober = PlanSession(self.scenario, "paper")
            found = self._truths[key] = self._prober.truth_at(robot, pose)
            self._changed()
        return found

    def leg(
        self,
        here: Stand,
        to: Stand,
        direction: float,
        name: str,
        margins: tuple[float, ...],
        heading: float,
    ) -> TableLeg | None:
        """The leg from ``here`` to ``to`` with the children in formation ``name``, the
        parent arriving with ``heading`` (rad); None where they have no room."""
        key = (here.index, to.index, direction, name, margins, heading)
        if key in self.legs:
            return self.legs[key]
        parent = self.plan.parent
        instrument = self.plan.start[parent].instrument
        assert instrument is not None
        found = formation(
            self.scenario.space,
            self.marker.cubes_body,
            self.instrument_range,
            self.path,
            to.arc,
            here.xy,
            to.xy,
            direction,
            self.forms[name],
            float(instrument[2]),
            None,
            margins,
        )
        leg = None
        if found is not None:
            order = self.children_order(direction)
            drives: list[tuple[str, NDArray[np.float64]]] = []
            stops: dict[str, NDArray[np.float64]] = {}
            for child, stop in zip(order, found[1], strict=True):
                drives.append((child, np.array([*stop.xy, stop.yaw])))
                stops[child] = drives[-1][1][:2]
            drives.append((parent, np.array([*to.xy, heading])))
            stops[parent] = drives[-1][1][:2]
            fixed = tuple(c for c in self.plan.children if c in stops)
            leg = TableLeg(tuple(drives), fixed, stops)
        self.legs[key] = leg
        self._changed()
        return leg

    def leg_steps(self, leg: TableLeg) -> tuple[Step, ...]:
        """A leg's steps: each child's drive and placement, the parent's drive, the fix
        (the robots' truths probed the first time)."""
        if leg.steps is None:
            steps: list[Step] = []
            for robot, pose in leg.drives:
                steps.append(Drive(robot, pose, self.truth(robot, pose)))
                if robot != self.plan.parent:
                    steps.append(Place(robot))
            steps.append(Fix(leg.fixed))
            leg.steps = tuple(steps)
            self._changed()
        return leg.steps

    def data_steps(self, station: str, visit: int) -> tuple[Step, ...]:
        """The steps of the data set and calibration at ``station``, as visit ``visit`` of
        its camera."""
        key = (station, visit)
        steps = self._data_steps.get(key)
        if steps is None:
            data = self.station_data(station)
            assert data is not None
            steps = tuple(_renumbered(s, visit) for s in data.steps)
            self._data_steps[key] = steps
        return steps

    # -- on disk ---------------------------------------------------------------------------
    _SAVED = (
        "plan", "start", "start_time", "speed", "start_xy", "ready_xy", "data", "_overhead",
        "recorded", "legs", "_truths",
    )  # fmt: skip

    def state(self) -> dict[str, Any]:
        """What the table's file keeps (:mod:`twin.envs.stand_cache`)."""
        return {name: getattr(self, name) for name in self._SAVED}

    def _restore(self, state: dict[str, Any]) -> None:
        for name in self._SAVED:
            setattr(self, name, state[name])
        self.plan = replace(self.plan, scenario=self.scenario)
        self._where: dict[str, NDArray[np.float64]] = {}

    def _size(self) -> int:
        return len(self.legs) + len(self._truths) + len(self.data) + self.recorded

    def _changed(self) -> None:
        """Save the table when it grew and the last save is :data:`SAVE_EVERY` s old."""
        if time.monotonic() - self._saved_at >= SAVE_EVERY:
            self.save()

    def save(self) -> None:
        """Write the table to its file (:mod:`twin.envs.stand_cache`) if it grew since it
        was read or last written."""
        size = self._size()
        if size != self._saved_size:
            write_table(self.scenario, self.layout, self.state())
            self._saved_size = size
        self._saved_at = time.monotonic()

    def close(self) -> None:
        """Save the table and free the site's worlds."""
        try:
            self.save()
        finally:
            for session in (self._recorder, self._prober):
                if session is not None:
                    session.close()
            self._recorder = self._prober = None


def _calibrates(steps: tuple[Step, ...]) -> bool:
    return any(isinstance(s, Calibrate) for s in steps)
