"""Where things stand: the world frame, and each camera, robot, control point and moved
camera inside the space and outside the obstacles.

- the parent starts at the origin heading along x and the floor lies the instrument's
  height below the origin (the world frame W is the parent's instrument frame at its start);
- the robots' start footprints lie on free floor and do not overlap;
- every camera and control point lies inside the space and outside the obstacles (below
  their tops);
- every moved camera (``faults.moved_cameras``) names a camera, once, and stays inside
  the space.
"""

from __future__ import annotations

import numpy as np

from twin.scenario.errors import ScenarioIssue
from twin.scenario.geometry import inside_obstacles, inside_space, rectangle
from twin.scenario.robots import INSTRUMENT_HEIGHT, PIONEER3AT
from twin.scenario.schema import Scenario

# Clearance kept between a robot's centre and walls or obstacles, m: its footprint's
# enclosing radius.
PARENT_CLEARANCE = PIONEER3AT.radius


# Smallest gap between two robots' start footprints, m.
START_GAP = 0.05


def free_issue(
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


def check_world_frame(sc: Scenario) -> list[ScenarioIssue]:
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


def check_cameras(sc: Scenario) -> list[ScenarioIssue]:
    """``cameras``: each inside the space and outside the obstacles (below their tops)."""
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


def check_robots(sc: Scenario) -> list[ScenarioIssue]:
    """``robots``: each starts on free floor, its footprint clear of the others'."""
    issues = []
    for i, robot in enumerate(sc.robots.all):
        key = "robots.parent.start_xy" if i == 0 else f"robots.children[{i - 1}].start_xy"
        issue = free_issue(
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


def check_control_points(sc: Scenario) -> list[ScenarioIssue]:
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


def check_moved_cameras(sc: Scenario) -> list[ScenarioIssue]:
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
