"""Paths on the floor: the group's route and the people's walks.

- the route starts (and, returning, ends) where the parent does, and stays inside the walls
  and clear of the obstacles by the parent's radius;
- people's paths stay inside the walls (they may cross obstacles' footprints: a person
  can walk past a low structure).
"""

from __future__ import annotations

import numpy as np

from twin.scenario.cross_checks.placement import PARENT_CLEARANCE
from twin.scenario.errors import ScenarioIssue
from twin.scenario.geometry import inside_obstacles, inside_space, polyline_points
from twin.scenario.schema import Scenario

ROUTE_START = 0.5
"""The route starts this close to the parent's start at most, m: the campaign walks the
route from its first waypoint (a route that starts elsewhere would send the parent there
without CPS, or leave W's origin off the route)."""


def check_route(sc: Scenario) -> list[ScenarioIssue]:
    """``route``: starts (and, returning, ends) at the parent's start; clear of walls and
    obstacles by the parent's radius."""
    issues = []
    first = np.asarray(sc.route.waypoints[0], dtype=float)
    start = np.asarray(sc.robots.parent.start_xy, dtype=float)
    if np.linalg.norm(first - start) > ROUTE_START:
        issues.append(
            ScenarioIssue(
                "route.waypoints[0]",
                f"the route starts {np.linalg.norm(first - start):.2f} m from the parent's "
                f"start {list(sc.robots.parent.start_xy)}",
                list(sc.route.waypoints[0]),
                f"a route that starts where the parent does (within {ROUTE_START} m)",
            )
        )
    last = np.asarray(sc.route.waypoints[-1], dtype=float)
    if sc.route.return_to_start and np.linalg.norm(last - start) > ROUTE_START:
        n = len(sc.route.waypoints) - 1
        issues.append(
            ScenarioIssue(
                f"route.waypoints[{n}]",
                f"route.return_to_start is set but the route ends "
                f"{np.linalg.norm(last - start):.2f} m from the parent's start",
                list(sc.route.waypoints[-1]),
                f"a route that ends where the parent started (within {ROUTE_START} m)",
            )
        )
    pts, seg = polyline_points(sc.route.waypoints, spacing=0.05)
    margin = PARENT_CLEARANCE
    # What each sample runs through: the walls first, then each obstacle.
    closer = f"closer than {margin:.2f} m"
    wall = ~inside_space(sc.space, pts, margin)
    through = [(wall, f"a wall or {closer} to one", "a route inside the space")]
    hits = inside_obstacles(sc.space.obstacles, pts, margin)
    through += [
        (hit, f"obstacle {ob.name!r} (or {closer})", "a route clear of the obstacles")
        for ob, hit in zip(sc.space.obstacles, hits, strict=True)
    ]
    reported: set[int] = set()
    for hit, what, expected in through:
        for k in np.flatnonzero(hit):
            i = int(seg[k])
            if i in reported:
                continue
            reported.add(i)
            issues.append(
                ScenarioIssue(
                    f"route.waypoints[{i}]",
                    f"route segment {i}->{i + 1} runs through {what}, near "
                    f"({pts[k, 0]:.2f}, {pts[k, 1]:.2f})",
                    [list(sc.route.waypoints[i]), list(sc.route.waypoints[i + 1])],
                    expected,
                )
            )
    return issues


# Clearance kept between a walking person's path and the walls, m.
PERSON_CLEARANCE = 0.25


def check_people(sc: Scenario) -> list[ScenarioIssue]:
    """``people``: each path stays inside the walls by ``PERSON_CLEARANCE``."""
    issues = []
    for i, person in enumerate(sc.people):
        pts, seg = polyline_points(person.waypoints, spacing=0.05)
        bad = ~inside_space(sc.space, pts, PERSON_CLEARANCE)
        if bad.any():
            k = int(np.argmax(bad))
            j = int(seg[k])
            issues.append(
                ScenarioIssue(
                    f"people[{i}].waypoints[{j}]",
                    f"person {person.name!r} walks through a wall or closer than "
                    f"{PERSON_CLEARANCE:.2f} m to one, near ({pts[k, 0]:.2f}, {pts[k, 1]:.2f})",
                    [list(person.waypoints[j]), list(person.waypoints[j + 1])],
                    "a path inside the space",
                )
            )
    return issues
