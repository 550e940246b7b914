"""Names across sections: unique where MuJoCo or the campaign needs them to be, and none
that the scene builder keeps for itself.

- names are unique (cameras; robots and people; obstacles and floor patches, which share
  MuJoCo's geom names) and none is one the scene builder uses itself (``floor``,
  ``wall_*``).
"""

from __future__ import annotations

from twin.scenario.errors import ScenarioIssue
from twin.scenario.schema import Scenario

# Geom names the scene builder (twin.sim.hall) gives the space itself; an obstacle or floor
# patch may not take them, nor any name starting with ``wall_``.
RESERVED_NAMES = ("floor", "wall_south", "wall_north", "wall_west", "wall_east")


RESERVED_PREFIXES = ("wall_",)


def check_names(sc: Scenario) -> list[ScenarioIssue]:
    """Unique names within each group that shares a namespace; none of the space's own."""
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
