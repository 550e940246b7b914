"""The checks of the children's stops in a formation's search, each place's found once:
fits, range and sight of the instrument's two stations, the other children.

Planned on the map and the campaign's estimates; nothing is measured here.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.rotation import wrap_angle
from twin.campaign.plan.clearance import (
    body_points,
    child_profile,
    in_range,
    passes_near,
    robot_fits,
    sight_clear,
)
from twin.campaign.plan.occlusion import unhidden_yaw
from twin.campaign.plan.route import RoutePath
from twin.campaign.plan.stop import Stop
from twin.scenario.schema import Space

MIN_SEPARATION = math.radians(4.0)
"""Least angle between the two children seen from the parent, so that an aim at one is
not nearer the other (a parent that just moved knows its heading to about a degree)."""

FORMATION_CLEARANCE = 0.35
"""Distance kept between a child's centre and walls in the formation, m (its radius, 0.29 m,
and its stopping error: narrow corridors need the children close to the walls)."""


class FormationChecks:
    """The checks of the children's stops in one search of a formation
    (:func:`twin.campaign.plan.formation.formation`), what each child's place needs alone
    found once (a search tries a place in many pairs).

    A pair of stops suits both stations where each child fits (:data:`FORMATION_CLEARANCE`)
    1 m from each instrument, every prism is in range and in sight of both (by a margin);
    the far child's prisms are clear of the waiting child from the current station; the
    two stand 1 m apart, neither hides the other's prisms, and their bearings from each
    station differ by :data:`MIN_SEPARATION`. Their headings keep every prism clear of its
    own assembly (:func:`unhidden_yaw`).

    Args:
        space: the map. cubes: (3, 3) the marker's prisms in the child's body frame, m.
        stations: (2,) (3,) the instrument at the parent's current and next station, m.
        instrument_range: the total station's (least, greatest) distance, m.
        waiting_xy: (2,) where the other child waits, m, or None.
    """

    def __init__(
        self,
        space: Space,
        cubes: NDArray[np.float64],
        stations: list[NDArray[np.float64]],
        instrument_range: tuple[float, float],
        waiting_xy: ArrayLike | None,
    ) -> None:
        self.space, self.cubes, self.stations = space, cubes, stations
        self.instrument_range = instrument_range
        self.waiting = None if waiting_xy is None else np.asarray(waiting_xy, dtype=float)
        self.profile = child_profile(space.floor_z)
        self._spots: dict[tuple[float, float], tuple[NDArray[np.float64], float]] = {}
        self._turned: dict[tuple[bytes, float], Stop | None] = {}
        self._free: dict[bytes, bool] = {}
        self._stops: dict[tuple[bytes, float], StopChecks] = {}

    def spot(
        self, path: RoutePath, s_next: float, direction: float, ahead: float, side: float
    ) -> tuple[NDArray[np.float64], float]:
        """The (2,) place (m) and heading (rad) of a child ``ahead`` (m) of ``s_next`` along
        the route and ``side`` (m) off it, as :func:`formation` places them."""
        key = (ahead, side)
        if key not in self._spots:
            s = s_next + direction * ahead
            yaw = path.heading(s) + (0.0 if direction > 0 else math.pi)
            self._spots[key] = (path.offset(s, side * direction), yaw)
        return self._spots[key]

    def turned(self, xy: NDArray[np.float64], yaw: float) -> Stop | None:
        """The stop at ``xy`` turned from ``yaw`` so that no prism is hidden
        (:func:`unhidden_yaw`); None where no heading is."""
        key = (np.asarray(xy, dtype=float).tobytes(), yaw)
        if key not in self._turned:
            turned = unhidden_yaw(xy, yaw, self.cubes, self.stations, self.space.floor_z)
            self._turned[key] = None if turned is None else Stop(xy, turned)
        return self._turned[key]

    def free(self, xy: NDArray[np.float64]) -> bool:
        """Whether a child fits at ``xy`` ((2,) m) and stands 1 m from each instrument."""
        p = np.asarray(xy, dtype=float).reshape(1, 2)
        key = p.tobytes()
        if key not in self._free:
            self._free[key] = bool(robot_fits(self.space, p, FORMATION_CLEARANCE)[0]) and all(
                np.linalg.norm(p - inst[:2], axis=1)[0] >= 1.0 for inst in self.stations
            )
        return self._free[key]

    def _stop(self, stop: Stop) -> StopChecks:
        xy = np.asarray(stop.xy, dtype=float).reshape(2)
        key = (xy.tobytes(), float(stop.yaw))
        if key not in self._stops:
            pts = body_points(xy, stop.yaw, self.cubes, self.space.floor_z)[0]
            self._stops[key] = StopChecks(xy, pts, self)
        return self._stops[key]

    def alone_ok(self, stop: Stop, sight_margin: float, first: bool) -> bool:
        """What a pair asks of one child's stop alone: free, in range and in
        sight of both stations by ``sight_margin`` (m); the ``first`` to move, clear of
        the waiting child."""
        if not self.free(stop.xy):
            return False
        kept = self._stop(stop)
        return kept.seen(sight_margin) and (not first or kept.clear_of_waiting())

    def pair_ok(self, stops: list[Stop], sight_margin: float) -> bool:
        """Whether the two stops (the far child's first) suit both stations."""
        # What each stop needs alone is kept: the pairs that fail on it fail at once.
        if not (
            self.alone_ok(stops[0], sight_margin, True)
            and self.alone_ok(stops[1], sight_margin, False)
        ):
            return False
        far, near = self._stop(stops[0]), self._stop(stops[1])
        if np.linalg.norm(far.xy - near.xy) < 1.0:
            return False
        for e, inst in enumerate(self.stations):
            sep = abs(wrap_angle(far.bearings[e] - near.bearings[e]))
            if sep < MIN_SEPARATION:
                return False
            for one, other in ((far, near), (near, far)):
                if passes_near(inst, one.pts, other.xy, self.profile).any():
                    return False
        return True


class StopChecks:
    """A child's stop in a :class:`FormationChecks` search: what it needs of the instrument's
    stations alone, each found once.

    Attributes:
        xy: (2,) m. pts: (3, 3) its prisms, m (W). bearings: its bearing from each
        station, rad.
    """

    def __init__(self, xy: NDArray[np.float64], pts: NDArray[np.float64], checks: FormationChecks):
        self.xy, self.pts, self._checks = xy, pts, checks
        self.bearings = []
        for inst in checks.stations:
            v = xy - inst[:2]
            self.bearings.append(math.atan2(v[1], v[0]))
        self._in_range: bool | None = None
        self._seen: dict[float, bool] = {}
        self._waiting: bool | None = None

    def seen(self, margin: float) -> bool:
        """Whether every prism is in range of each station and in sight, by ``margin``
        (m)."""
        c = self._checks
        if self._in_range is None:
            self._in_range = all(
                in_range(np.linalg.norm(self.pts - inst, axis=1), c.instrument_range).all()
                for inst in c.stations
            )
        if not self._in_range:
            return False
        if margin not in self._seen:
            self._seen[margin] = all(
                sight_clear(c.space, inst, self.pts, margin).all() for inst in c.stations
            )
        return self._seen[margin]

    def clear_of_waiting(self) -> bool:
        """Whether the waiting child leaves the prisms clear from the current station (as
        the far child)."""
        c = self._checks
        if c.waiting is None:
            return True
        if self._waiting is None:
            far = self.pts
            self._waiting = not passes_near(c.stations[0], far, c.waiting, c.profile).any()
        return self._waiting
