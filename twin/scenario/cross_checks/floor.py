"""The floor's own pieces: obstacles a robot cannot drive over unseen, and tilted patches
clear of the obstacles and of each other.

- obstacles (the lowest step of a staircase included) are taller than the robots' ground
  clearance (only the chassis collides with them);
- floor patches overlap no obstacle and no other patch, and lie inside the space.
"""

from __future__ import annotations

import shapely

from twin.scenario.errors import ScenarioIssue
from twin.scenario.geometry import inside_space, rectangle
from twin.scenario.robots import PLATFORMS
from twin.scenario.schema import Scenario

# Lowest obstacle (or lowest stair step) a robot's chassis still hits, m: anything lower
# passes under the highest chassis unseen.
MIN_OBSTACLE_HEIGHT = max(p.ground_clearance for p in PLATFORMS.values())


def check_obstacles(sc: Scenario) -> list[ScenarioIssue]:
    """``space.obstacles``: each taller (its lowest step too) than the robots' ground
    clearance."""
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


def check_patches(sc: Scenario) -> list[ScenarioIssue]:
    """``space.floor_patches``: inside the walls, clear of the obstacles and of each other."""
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
