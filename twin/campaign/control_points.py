"""Control points measured as the route passes them (``[[control_points]]``).

After each CPS fix (and at the first station) the parent measures every control point
within its ``sight_radius_m``: one shot, aimed where the point is expected (its surveyed
position, or where the parent first measured it, or, before that, where the scenario puts
it). Each measurement is recorded (``/campaign/control_sighting``) for the global
adjustment, which closes the loop with it; a point that does not answer, or answers too
far from where it is expected (another prism in the aim's cone; the parent's own
uncertainty widens the gate, :func:`later_gate`), is a failure
(``control_point_not_seen``, ``control_point_mismatch``) and is not recorded. At the end,
a point never measured, or measured once only, is a failure too (it closes no loop).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from twin.campaign.journal import Journal, RobotJournal
from twin.campaign.records import ControlSighting
from twin.campaign.shooting import shoot_at
from twin.hal.devices import TotalStation
from twin.instruments.noise import cartesian_covariance
from twin.localization.planar import world2level
from twin.localization.pose import ParentPose
from twin.scenario.schema import ControlPoint

FIRST_GATE_M = 0.5
"""How far a control point's first measurement may lie from the scenario's position, m."""

GATE_M = 0.15
"""How far a later measurement may lie from the first (or the surveyed position), m: the
parent's drift over a loop of a hall (tens of mm) passes; a child's prism (0.3 m and more
from any control point the route passes) does not."""

GATE_SIGMAS = 3.0
"""After a long travel the gate is this many standard deviations of the parent's
horizontal position (largest axis), where that is more than :data:`GATE_M`: the drift the
loop is there to close must not be what rejects it."""


def later_gate(parent: ParentPose) -> float:
    """How far a later measurement may lie from where it is expected, m (see
    :data:`GATE_M`, :data:`GATE_SIGMAS`)."""
    return max(GATE_M, GATE_SIGMAS * parent.horizontal_std)


class ControlPoints:
    """The control points of a campaign and where they are expected.

    Args:
        station: the parent's total station. journal: where sightings and failures go.
        points: the scenario's control points. lock_retries: re-aims after a lost lock.
    """

    def __init__(
        self,
        station: TotalStation,
        journal: Journal,
        points: Sequence[ControlPoint],
        lock_retries: int,
    ) -> None:
        self.station, self.journal = station, journal
        self.points = tuple(points)
        self.lock_retries = lock_retries
        self.expected: dict[str, NDArray[np.float64]] = {
            p.name: np.asarray(p.position, dtype=float) for p in self.points
        }
        self.measured: set[str] = {p.name for p in self.points if p.surveyed}
        self.sightings: dict[str, int] = {p.name: 0 for p in self.points}

    def sight(self, parent: ParentPose, parent_name: str) -> None:
        """Measure every control point within reach of the parent's current station."""
        for point in self.points:
            expected = self.expected[point.name]
            if np.hypot(*(expected[:2] - parent.translation[:2])) > point.sight_radius_m:
                continue
            report = RobotJournal(self.journal, parent_name)
            aim = world2level(expected, parent.yaw, parent.translation)
            shot = shoot_at(self.station, aim, self.lock_retries, report, 0)
            if shot is None:
                self.journal.failure(
                    "control_point_not_seen",
                    f"control point {point.name} did not answer",
                    parent_name,
                    point=point.name,
                )
                continue
            level = shot.to_cartesian()
            world = parent.level2world(level)
            gate = later_gate(parent) if point.name in self.measured else FIRST_GATE_M
            off = float(np.linalg.norm(world - expected))
            if off > gate:
                self.journal.failure(
                    "control_point_mismatch",
                    f"control point {point.name} measured {1e3 * off:.0f} mm from where it "
                    f"was expected (at most {1e3 * gate:.0f} mm): another prism?",
                    parent_name,
                    point=point.name,
                    offset_m=off,
                )
                continue
            if point.name not in self.measured:
                self.expected[point.name] = world
                self.measured.add(point.name)
            cov = cartesian_covariance(shot.polar, self.station.spec, self.station.inclinometer)
            self.journal.control_sighting(
                ControlSighting(self.journal.clock.now(), point.name, level, cov, world)
            )
            self.sightings[point.name] += 1

    def report_unseen(self, parent_name: str) -> None:
        """At the end: a failure (``control_point_never_seen``) for each control point the
        route never brought within its ``sight_radius_m`` (or that never answered), and
        one (``control_point_seen_once``) for each measured only once and not surveyed: the
        adjustment can use neither."""
        for point in self.points:
            n = self.sightings[point.name]
            if n == 0:
                self.journal.failure(
                    "control_point_never_seen",
                    f"control point {point.name} was never measured: no station within "
                    f"{point.sight_radius_m:g} m of it saw it",
                    parent_name,
                    point=point.name,
                )
            elif n == 1 and not point.surveyed:
                self.journal.failure(
                    "control_point_seen_once",
                    f"control point {point.name} was measured from one station only: it "
                    "closes no loop",
                    parent_name,
                    point=point.name,
                )
