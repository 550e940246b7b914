"""Cross-checks between a scenario's sections, each producing a :class:`ScenarioIssue`.

- every camera, robot start, floor patch and calibration station lies inside the space and
  outside the obstacles;
- the route stays inside the walls and clear of the obstacles by the parent's radius;
- every calibration visit names a camera, and from its station the total station sees at
  least ``calibration.min_visible_fraction`` of the camera's view of the floor (line of
  sight to the corner cubes of a child standing there, within the instrument's range).
"""

from __future__ import annotations

import numpy as np

from twin.scenario.errors import ScenarioIssue
from twin.scenario.geometry import (
    floor_view,
    inside_obstacle,
    inside_space,
    polyline_points,
    segment_blocked,
)
from twin.scenario.robots import INSTRUMENT_HEIGHT, PIONEER3AT, PIONEER3DX
from twin.scenario.schema import Scenario

# Clearance kept between a robot's centre and walls or obstacles, m: its footprint's
# enclosing radius.
PARENT_CLEARANCE = PIONEER3AT.radius
CHILD_CLEARANCE = PIONEER3DX.radius


def check_scenario(sc: Scenario) -> list[ScenarioIssue]:
    """Every cross-section problem of ``sc`` (empty when it is consistent)."""
    issues: list[ScenarioIssue] = []
    issues += _check_cameras(sc)
    issues += _check_robots(sc)
    issues += _check_patches(sc)
    issues += _check_route(sc)
    issues += _check_visits(sc)
    return issues


def _free_issue(
    sc: Scenario, key: str, xy: tuple[float, float], margin: float, what: str
) -> ScenarioIssue | None:
    """An issue if floor point ``xy`` is outside the space or in an obstacle (+ margin)."""
    if not inside_space(sc.space, [xy], margin)[0]:
        (x0, x1), (y0, y1) = sc.space.x_range, sc.space.y_range
        return ScenarioIssue(
            key,
            f"{what} lies outside the space or closer than {margin:.2f} m to a wall",
            list(xy),
            f"x in [{x0 + margin:.2f}, {x1 - margin:.2f}] and y in "
            f"[{y0 + margin:.2f}, {y1 - margin:.2f}] m",
        )
    for ob in sc.space.obstacles:
        if inside_obstacle(ob, [xy], margin)[0]:
            return ScenarioIssue(
                key,
                f"{what} lies inside obstacle {ob.name!r} (or closer than {margin:.2f} m)",
                list(xy),
                "a point on free floor",
            )
    return None


def _check_cameras(sc: Scenario) -> list[ScenarioIssue]:
    issues = []
    z0, z1 = sc.space.z_range
    for i, cam in enumerate(sc.cameras):
        key = f"cameras[{i}].position"
        x, y, z = cam.position
        (x0, x1), (y0, y1) = sc.space.x_range, sc.space.y_range
        if not (x0 <= x <= x1 and y0 <= y <= y1 and z0 < z < z1):
            issues.append(
                ScenarioIssue(
                    key,
                    f"camera {cam.name!r} lies outside the space",
                    list(cam.position),
                    f"x in [{x0:g}, {x1:g}], y in [{y0:g}, {y1:g}], z in ({z0:g}, {z1:g}) m",
                )
            )
            continue
        for ob in sc.space.obstacles:
            if inside_obstacle(ob, [(x, y)])[0] and z < z0 + ob.size[2]:
                issues.append(
                    ScenarioIssue(
                        key,
                        f"camera {cam.name!r} lies inside obstacle {ob.name!r}",
                        list(cam.position),
                        "a position in free space",
                    )
                )
    return issues


def _check_robots(sc: Scenario) -> list[ScenarioIssue]:
    issues = []
    for i, robot in enumerate(sc.robots.all):
        key = "robots.parent.start_xy" if i == 0 else f"robots.children[{i - 1}].start_xy"
        issue = _free_issue(
            sc, key, robot.start_xy, robot.platform.radius, f"start of {robot.name!r}"
        )
        if issue:
            issues.append(issue)
    return issues


def _check_patches(sc: Scenario) -> list[ScenarioIssue]:
    issues = []
    for i, patch in enumerate(sc.space.floor_patches):
        hx, hy = 0.5 * patch.size[0], 0.5 * patch.size[1]
        cx, cy = patch.center
        corners = [(cx - hx, cy - hy), (cx + hx, cy + hy)]
        if not inside_space(sc.space, corners).all():
            issues.append(
                ScenarioIssue(
                    f"space.floor_patches[{i}].center",
                    f"floor patch {patch.name!r} reaches outside the space",
                    list(patch.center),
                    "a patch wholly inside the walls",
                )
            )
    return issues


def _check_route(sc: Scenario) -> list[ScenarioIssue]:
    issues = []
    pts, seg = polyline_points(sc.route.waypoints, spacing=0.05)
    margin = PARENT_CLEARANCE
    bad_wall = ~inside_space(sc.space, pts, margin)
    reported: set[int] = set()
    for k in np.flatnonzero(bad_wall):
        i = int(seg[k])
        if i in reported:
            continue
        reported.add(i)
        issues.append(
            ScenarioIssue(
                f"route.waypoints[{i}]",
                f"route segment {i}->{i + 1} runs through a wall or closer than "
                f"{margin:.2f} m to one, near ({pts[k, 0]:.2f}, {pts[k, 1]:.2f})",
                [list(sc.route.waypoints[i]), list(sc.route.waypoints[i + 1])],
                "a route inside the space",
            )
        )
    for ob in sc.space.obstacles:
        hit = inside_obstacle(ob, pts, margin)
        for k in np.flatnonzero(hit):
            i = int(seg[k])
            if i in reported:
                continue
            reported.add(i)
            issues.append(
                ScenarioIssue(
                    f"route.waypoints[{i}]",
                    f"route segment {i}->{i + 1} runs through obstacle {ob.name!r} (or "
                    f"closer than {margin:.2f} m), near ({pts[k, 0]:.2f}, {pts[k, 1]:.2f})",
                    [list(sc.route.waypoints[i]), list(sc.route.waypoints[i + 1])],
                    "a route clear of the obstacles",
                )
            )
    return issues


def station_visibility(sc: Scenario, camera_name: str, station: tuple[float, float]) -> float:
    """Fraction of a camera's reachable floor view whose corner cubes the total station
    sees from ``station`` (line of sight clear of obstacles, slope distance in range).

    The view is sampled on a grid over the image; samples in obstacles or closer than a
    child's radius to a wall are not counted. Returns 0 when the camera sees no such floor.
    """
    cam = sc.camera(camera_name).tsai()
    floor = floor_view(cam, sc.space.floor_z, max_range=60.0)
    if len(floor) == 0:
        return 0.0
    ok = inside_space(sc.space, floor[:, :2], CHILD_CLEARANCE)
    for ob in sc.space.obstacles:
        ok &= ~inside_obstacle(ob, floor[:, :2], CHILD_CLEARANCE)
    floor = floor[ok]
    if len(floor) == 0:
        return 0.0
    cube_height = float(np.mean([c[2] for c in sc.marker.cubes]))
    targets = floor + np.array([0.0, 0.0, cube_height])
    inst = np.array([station[0], station[1], sc.space.floor_z + INSTRUMENT_HEIGHT])
    dist = np.linalg.norm(targets - inst, axis=1)
    ts = sc.noise.total_station
    in_range = (dist >= ts.range_min) & (dist <= ts.range_max)
    clear = ~segment_blocked(sc.space, np.broadcast_to(inst, targets.shape), targets)
    return float(np.mean(in_range & clear))


def _check_visits(sc: Scenario) -> list[ScenarioIssue]:
    issues = []
    names = [c.name for c in sc.cameras]
    for i, visit in enumerate(sc.calibration.visits):
        if visit.camera not in names:
            issues.append(
                ScenarioIssue(
                    f"calibration.visits[{i}].camera",
                    "unknown camera",
                    visit.camera,
                    f"one of {', '.join(names)}",
                )
            )
            continue
        key = f"calibration.visits[{i}].station"
        issue = _free_issue(sc, key, visit.station, PARENT_CLEARANCE, "the station")
        if issue:
            issues.append(issue)
            continue
        frac = station_visibility(sc, visit.camera, visit.station)
        need = sc.calibration.min_visible_fraction
        if frac < need:
            issues.append(
                ScenarioIssue(
                    key,
                    f"from this station the total station sees only {100 * frac:.0f} % of "
                    f"the floor seen by camera {visit.camera!r} (the rest is blocked or "
                    "out of range)",
                    list(visit.station),
                    f"a station that sees at least {100 * need:.0f} % of it "
                    "(calibration.min_visible_fraction)",
                )
            )
    return issues
