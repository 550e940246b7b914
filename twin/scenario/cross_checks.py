"""Cross-checks between a scenario's sections, each producing a :class:`ScenarioIssue`.

- names are unique (cameras; robots; obstacles and floor patches, which share MuJoCo's
  geom names) and none is one the scene builder uses itself (``floor``, ``wall_*``);
- the parent starts at the origin heading along x and the floor lies the instrument's
  height below the origin (the world frame W is the parent's instrument frame at its start);
- the robots' start footprints do not overlap;
- obstacles (the lowest step of a staircase included) are taller than the robots' ground
  clearance (only the chassis collides with them), and floor patches overlap no obstacle
  and no other patch;
- every camera, robot start, floor patch and calibration station lies inside the space and
  outside the obstacles;
- the route starts where the parent does and stays inside the walls and clear of the
  obstacles by the parent's radius;
- people's paths stay inside the walls (they may cross obstacles' footprints: a person
  can walk past a low structure), and their names differ from the robots';
- every calibration visit names a camera, and from its station the total station sees at
  least ``calibration.min_visible_fraction`` of the camera's view of the floor (line of
  sight to the corner cubes of a child standing there, within the instrument's range);
- every moved camera (``faults.moved_cameras``) names a camera, once, and stays inside
  the space.
"""

from __future__ import annotations

import numpy as np
import shapely

from twin.scenario.errors import ScenarioIssue
from twin.scenario.geometry import inside_obstacles, inside_space, polyline_points, rectangle
from twin.scenario.robots import INSTRUMENT_HEIGHT, PIONEER3AT, PLATFORMS
from twin.scenario.schema import Scenario
from twin.scenario.visibility import station_visibility

# Clearance kept between a robot's centre and walls or obstacles, m: its footprint's
# enclosing radius.
PARENT_CLEARANCE = PIONEER3AT.radius

# Geom names the scene builder (twin.sim.hall) gives the space itself; an obstacle or floor
# patch may not take them, nor any name starting with ``wall_``.
RESERVED_NAMES = ("floor", "wall_south", "wall_north", "wall_west", "wall_east")
RESERVED_PREFIXES = ("wall_",)

# Smallest gap between two robots' start footprints, m.
START_GAP = 0.05

# Lowest obstacle (or lowest stair step) a robot's chassis still hits, m: anything lower
# passes under the highest chassis unseen.
MIN_OBSTACLE_HEIGHT = max(p.ground_clearance for p in PLATFORMS.values())


def check_scenario(sc: Scenario) -> list[ScenarioIssue]:
    """Every cross-section problem of ``sc`` (empty when it is consistent)."""
    issues: list[ScenarioIssue] = []
    issues += _check_names(sc)
    issues += _check_world_frame(sc)
    issues += _check_cameras(sc)
    issues += _check_robots(sc)
    issues += _check_obstacles(sc)
    issues += _check_patches(sc)
    issues += _check_route(sc)
    issues += _check_visits(sc)
    issues += _check_people(sc)
    issues += _check_campaign(sc)
    issues += _check_moved_cameras(sc)
    issues += _check_control_points(sc)
    return issues


def _check_control_points(sc: Scenario) -> list[ScenarioIssue]:
    """``control_points``: unique names, inside the space, none inside an obstacle below its
    top (no instrument would see it there)."""
    issues = []
    seen: set[str] = set()
    (x0, x1), (y0, y1) = sc.space.x_range, sc.space.y_range
    z0, z1 = sc.space.z_range
    obstacles = sc.space.obstacles
    xyz = np.array([p.position for p in sc.control_points]).reshape(-1, 3)
    # buried[k, i]: point i lies in obstacle k, below its top.
    tops = np.array([z0 + ob.size[2] for ob in obstacles]).reshape(-1, 1)
    buried = inside_obstacles(obstacles, xyz[:, :2]) & (xyz[:, 2] < tops)
    for i, point in enumerate(sc.control_points):
        key = f"control_points[{i}]"
        if point.name in seen:
            issues.append(
                ScenarioIssue(
                    f"{key}.name",
                    f"control point names must be unique, repeated: {point.name}",
                    point.name,
                    "a name not used by another control point",
                )
            )
        seen.add(point.name)
        x, y, z = point.position
        if not (x0 <= x <= x1 and y0 <= y <= y1 and z0 < z < z1):
            issues.append(
                ScenarioIssue(
                    f"{key}.position",
                    f"control point {point.name!r} lies outside the space",
                    list(point.position),
                    f"x in [{x0:g}, {x1:g}], y in [{y0:g}, {y1:g}], z in ({z0:g}, {z1:g}) m",
                )
            )
            continue
        issues += [
            ScenarioIssue(
                f"{key}.position",
                f"control point {point.name!r} lies inside obstacle {obstacles[k].name!r} "
                f"(below its top, z = {z0 + obstacles[k].size[2]:g} m)",
                list(point.position),
                "a position on free floor or above the obstacle",
            )
            for k in np.flatnonzero(buried[:, i])
        ]
    return issues


def _check_moved_cameras(sc: Scenario) -> list[ScenarioIssue]:
    """``faults.moved_cameras``: each names a camera of the scenario, once, and leaves it
    inside the space."""
    issues = []
    names = [c.name for c in sc.cameras]
    seen: set[str] = set()
    (x0, x1), (y0, y1) = sc.space.x_range, sc.space.y_range
    z0, z1 = sc.space.z_range
    for i, fault in enumerate(sc.faults.moved_cameras):
        key = f"faults.moved_cameras[{i}]"
        if fault.camera not in names:
            issues.append(
                ScenarioIssue(
                    f"{key}.camera", "unknown camera", fault.camera, f"one of {', '.join(names)}"
                )
            )
            continue
        if fault.camera in seen:
            issues.append(
                ScenarioIssue(
                    f"{key}.camera",
                    "camera moved twice",
                    fault.camera,
                    "one entry per camera (add the shifts and turns into one)",
                )
            )
            continue
        seen.add(fault.camera)
        x, y, z = fault.moved(sc.camera(fault.camera).tsai()).position
        if not (x0 <= x <= x1 and y0 <= y <= y1 and z0 < z < z1):
            issues.append(
                ScenarioIssue(
                    f"{key}.shift",
                    f"camera {fault.camera!r} moves outside the space",
                    list(fault.shift),
                    f"a shift that keeps it in x [{x0:g}, {x1:g}], y [{y0:g}, {y1:g}], "
                    f"z ({z0:g}, {z1:g}) m",
                )
            )
    return issues


def _check_campaign(sc: Scenario) -> list[ScenarioIssue]:
    issues = []
    names = [c.name for c in sc.cameras]
    for i, name in enumerate(sc.campaign.reference_cameras or ()):
        if name not in names:
            issues.append(
                ScenarioIssue(
                    f"campaign.reference_cameras[{i}]",
                    "unknown camera",
                    name,
                    f"one of {', '.join(names)}",
                )
            )
    if sc.campaign.min_points > sc.campaign.station_points:
        issues.append(
            ScenarioIssue(
                "campaign.min_points",
                f"more than the {sc.campaign.station_points} points a station gathers",
                sc.campaign.min_points,
                "at most campaign.station_points",
            )
        )
    if len(sc.robots.children) < 2:
        issues.append(
            ScenarioIssue(
                "robots.children",
                "CPS needs two children (one moves while the other stays)",
                len(sc.robots.children),
                "at least 2 children",
            )
        )
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
    inside = np.flatnonzero(inside_obstacles(sc.space.obstacles, [xy], margin)[:, 0])
    if inside.size:
        return ScenarioIssue(
            key,
            f"{what} lies inside obstacle {sc.space.obstacles[inside[0]].name!r} (or closer "
            f"than {margin:.2f} m)",
            list(xy),
            "a point on free floor",
        )
    return None


def _check_names(sc: Scenario) -> list[ScenarioIssue]:
    issues = []
    robot_keys = ["robots.parent.name"] + [
        f"robots.children[{i}].name" for i in range(len(sc.robots.children))
    ]
    groups = [
        ("camera", [(f"cameras[{i}].name", c.name) for i, c in enumerate(sc.cameras)]),
        (
            "robot and person",
            list(zip(robot_keys, [r.name for r in sc.robots.all], strict=True))
            + [(f"people[{i}].name", p.name) for i, p in enumerate(sc.people)],
        ),
        (
            "obstacle and floor patch",
            [(f"space.obstacles[{i}].name", o.name) for i, o in enumerate(sc.space.obstacles)]
            + [
                (f"space.floor_patches[{i}].name", p.name)
                for i, p in enumerate(sc.space.floor_patches)
            ],
        ),
    ]
    for what, named in groups:
        seen: set[str] = set()
        for key, name in named:
            if name in seen:
                issues.append(
                    ScenarioIssue(
                        key,
                        f"{what} names must be unique, repeated: {name}",
                        name,
                        f"a name not used by another {what}",
                    )
                )
            seen.add(name)
    for key, name in groups[2][1]:
        if name in RESERVED_NAMES or name.startswith(RESERVED_PREFIXES):
            issues.append(
                ScenarioIssue(
                    key,
                    "name reserved for the space's own floor and walls",
                    name,
                    "a name other than floor and wall_*",
                )
            )
    return issues


def _check_world_frame(sc: Scenario) -> list[ScenarioIssue]:
    """W is the parent's instrument frame at its start: the parent starts at the origin,
    heading along x, and the floor lies the instrument's height below the origin."""
    issues = []
    parent = sc.robots.parent
    why = "the world frame is the parent's instrument frame at its start"
    if tuple(parent.start_xy) != (0.0, 0.0):
        issues.append(
            ScenarioIssue(
                "robots.parent.start_xy",
                f"the parent must start at the origin ({why})",
                list(parent.start_xy),
                "[0.0, 0.0] (move the space, obstacles, cameras and route instead)",
            )
        )
    if parent.start_yaw_deg != 0.0:
        issues.append(
            ScenarioIssue(
                "robots.parent.start_yaw_deg",
                f"the parent must start heading along x ({why})",
                parent.start_yaw_deg,
                "0.0 (turn the rest of the scenario instead)",
            )
        )
    if abs(sc.space.floor_z + INSTRUMENT_HEIGHT) > 1e-9:
        issues.append(
            ScenarioIssue(
                "space.floor_z",
                "the floor must lie the total station's height below the origin (the "
                f"origin is the instrument on the parent, {INSTRUMENT_HEIGHT:.2f} m above "
                "the floor)",
                sc.space.floor_z,
                f"{-INSTRUMENT_HEIGHT:.2f}",
            )
        )
    return issues


def _check_cameras(sc: Scenario) -> list[ScenarioIssue]:
    issues = []
    z0, z1 = sc.space.z_range
    obstacles = sc.space.obstacles
    xyz = np.array([cam.position for cam in sc.cameras])
    # inside[k, i]: camera i lies in obstacle k, below its top.
    tops = np.array([z0 + ob.size[2] for ob in obstacles]).reshape(-1, 1)
    inside = inside_obstacles(obstacles, xyz[:, :2]) & (xyz[:, 2] < tops)
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
        issues += [
            ScenarioIssue(
                key,
                f"camera {cam.name!r} lies inside obstacle {obstacles[k].name!r}",
                list(cam.position),
                "a position in free space",
            )
            for k in np.flatnonzero(inside[:, i])
        ]
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
    robots = sc.robots.all
    shapes = [
        rectangle(r.start_xy, (r.platform.length, r.platform.width), r.start_yaw) for r in robots
    ]
    for j in range(1, len(robots)):
        for i in range(j):
            if shapes[i].distance(shapes[j]) < START_GAP:
                issues.append(
                    ScenarioIssue(
                        f"robots.children[{j - 1}].start_xy",
                        f"the start footprint of {robots[j].name!r} overlaps that of "
                        f"{robots[i].name!r} (or comes closer than {START_GAP:.2f} m)",
                        list(robots[j].start_xy),
                        f"robots that start at least {START_GAP:.2f} m apart",
                    )
                )
    return issues


def _check_obstacles(sc: Scenario) -> list[ScenarioIssue]:
    issues = []
    for i, ob in enumerate(sc.space.obstacles):
        lowest = ob.size[2] / ob.steps if ob.kind == "stairs" else ob.size[2]
        if lowest <= MIN_OBSTACLE_HEIGHT:
            what = "its lowest step" if ob.kind == "stairs" else "it"
            issues.append(
                ScenarioIssue(
                    f"space.obstacles[{i}].size",
                    f"obstacle {ob.name!r} is so low that robots would drive over {what} "
                    f"unseen ({lowest:.3f} m; only the chassis collides with obstacles, "
                    f"and it clears the floor by up to {MIN_OBSTACLE_HEIGHT:.2f} m)",
                    list(ob.size),
                    f"an obstacle{' step' if ob.kind == 'stairs' else ''} taller than "
                    f"{MIN_OBSTACLE_HEIGHT:.2f} m",
                )
            )
    return issues


def _overlap(a: shapely.Polygon, b: shapely.Polygon) -> bool:
    """Whether two footprints share area (touching is not overlapping)."""
    return a.intersection(b).area > 0.0


def _check_patches(sc: Scenario) -> list[ScenarioIssue]:
    issues = []
    obstacles = [(ob, rectangle(ob.center, ob.size[:2], ob.yaw)) for ob in sc.space.obstacles]
    patches = [rectangle(p.center, p.size) for p in sc.space.floor_patches]
    for i, patch in enumerate(sc.space.floor_patches):
        for ob, foot in obstacles:
            if _overlap(patches[i], foot):
                issues.append(
                    ScenarioIssue(
                        f"space.floor_patches[{i}].center",
                        f"floor patch {patch.name!r} overlaps obstacle {ob.name!r}",
                        list(patch.center),
                        "a patch on free floor, clear of the obstacles",
                    )
                )
        for k in range(i):
            if _overlap(patches[i], patches[k]):
                other = sc.space.floor_patches[k].name
                issues.append(
                    ScenarioIssue(
                        f"space.floor_patches[{i}].center",
                        f"floor patch {patch.name!r} overlaps floor patch {other!r}",
                        list(patch.center),
                        "floor patches that do not overlap",
                    )
                )
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


ROUTE_START = 0.5
"""The route starts this close to the parent's start at most, m: the campaign walks the
route from its first waypoint (a route that starts elsewhere would send the parent there
without CPS, or leave W's origin off the route)."""


def _check_route(sc: Scenario) -> list[ScenarioIssue]:
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
    hits = inside_obstacles(sc.space.obstacles, pts, margin)
    for ob, hit in zip(sc.space.obstacles, hits, strict=True):
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


def scenario_station_visibility(
    sc: Scenario, camera_name: str, station: tuple[float, float]
) -> float:
    """:func:`twin.scenario.visibility.station_visibility` of a scenario's camera from
    ``station``, with the scenario's own instrument (its range) and marker (the prisms'
    mean height)."""
    ts = sc.noise.total_station
    return station_visibility(
        sc.space,
        sc.camera(camera_name).tsai(),
        station,
        sc.space.floor_z + INSTRUMENT_HEIGHT,
        float(np.mean([c[2] for c in sc.marker.cubes])),
        (ts.range_min, ts.range_max),
    )


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
        frac = scenario_station_visibility(sc, visit.camera, visit.station)
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


# Clearance kept between a walking person's path and the walls, m.
PERSON_CLEARANCE = 0.25


def _check_people(sc: Scenario) -> list[ScenarioIssue]:
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
