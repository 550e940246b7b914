"""A space whose blocked floor is its map's (``[space.map]``): the map read again, checked
against its hash, and laid as boxes the way ``twin site`` laid it.

The boxes are axis-aligned and rectilinear on a grid: a convex decomposition of the blocked
floor that MuJoCo collides exactly (a mesh of an L- or U-shaped wall would be collided as
its convex hull), and that every fidelity reads as ordinary obstacles.
"""

from __future__ import annotations

import functools
import json
import math
import os
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from twin.scenario.errors import ScenarioError, ScenarioIssue
from twin.scenario.schema import Obstacle, Scenario, SpaceMap

PLACE_TOLERANCE = 1e-6
"""How far the space's written ``origin`` and ``size`` may lie from the map's, m."""


def map_path(ref: SpaceMap, scenario_file: str | Path) -> Path:
    """The map file ``ref`` names: as written if absolute, else in the scenario file's
    folder (the working folder for a scenario not read from a file, ``<dict>``)."""
    path = Path(ref.file)
    if path.is_absolute():
        return path
    folder = Path.cwd() if str(scenario_file).startswith("<") else Path(scenario_file).parent
    # The folder as the system finds it, then ``..`` taken lexically: the scenario's own
    # folder need not exist yet (``twin site`` checks its scenario before writing it).
    return Path(os.path.normpath(folder.resolve() / path))


def with_map_boxes(sc: Scenario, scenario_file: str | Path) -> Scenario:
    """``sc`` with its map's boxes after its own obstacles (itself if it has no map).

    Raises:
        ScenarioError: the map is missing or unreadable, its content does not hash to
            ``space.map.sha256`` (the message names the file and both hashes), an option
            its reader does not take, or a space whose origin or size is not the map's.
    """
    ref = sc.space.map
    if ref is None:
        return sc
    from twin.planning.floor_map import MapError
    from twin.planning.map_files import map_sha256

    path = map_path(ref, scenario_file)

    def refuse(key: str, problem: str, value: object, expected: str) -> ScenarioError:
        return ScenarioError(scenario_file, [ScenarioIssue(key, problem, value, expected)])

    if not path.is_file():
        raise refuse(
            "space.map.file",
            f"the map {path} does not exist",
            ref.file,
            "the map the scenario was planned on, relative to the scenario file's folder",
        )
    try:
        found = map_sha256(path)
    except MapError as exc:
        raise refuse("space.map.file", str(exc), ref.file, "a readable map") from None
    if found != ref.sha256:
        raise refuse(
            "space.map.sha256",
            f"the map {path} has the sha256 {found}, not the scenario's",
            ref.sha256,
            "the map the scenario was planned on (plan the site again with twin site for this map)",
        )
    options = json.dumps(ref.options, sort_keys=True)
    try:
        boxes, origin, size = _map_boxes(
            str(path.resolve()), found, options, ref.pose, ref.resolution, sc.space.size[2]
        )
    except MapError as exc:
        raise refuse("space.map.file", str(exc), ref.file, "a map its reader reads") from None
    except TypeError as exc:
        raise refuse(
            "space.map.options", str(exc), dict(ref.options), "the reader's keyword options"
        ) from None
    except (ValueError, ValidationError) as exc:
        raise refuse("space.map", str(exc), None, "a map laid as boxes") from None
    for key, written, built in (("origin", sc.space.origin, origin), ("size", sc.space.size, size)):
        if any(abs(a - b) > PLACE_TOLERANCE for a, b in zip(written, built, strict=True)):
            raise refuse(
                f"space.{key}",
                f"not the map's (the map {path} laid from space.map.pose gives {list(built)})",
                list(written),
                "the space twin site wrote for this map and pose",
            )
    return sc.model_copy(update={"space": sc.space.with_map_boxes(boxes)})


@functools.lru_cache(maxsize=4)
def _map_boxes(
    path: str,
    sha256: str,
    options: str,
    pose: tuple[float, float, float],
    resolution: float,
    ceiling: float,
) -> tuple[tuple[Obstacle, ...], tuple[float, float], tuple[float, float, float]]:
    """The map's boxes as obstacles, the room's origin and size (W, m); cached by the map's
    content (``sha256``) and how it is laid."""
    import dataclasses

    from twin.planning.boxes import boxed_space
    from twin.planning.frames import MapPose
    from twin.planning.maps import load_map

    floor = load_map(path, **json.loads(options))
    floor = dataclasses.replace(floor, height=ceiling)
    boxed = boxed_space(floor, MapPose(pose[0], pose[1], math.radians(pose[2])), resolution)
    obstacles = tuple(map_obstacle(k, box) for k, box in enumerate(boxed.boxes))
    return obstacles, boxed.origin, boxed.size


def map_obstacle(k: int, box: Any) -> Obstacle:
    """The ``k``-th box of a map (a :class:`twin.planning.boxes.Box`) as an obstacle
    ``map_k``."""
    return Obstacle(
        name=f"map_{k}",
        center=(float(box.center[0]), float(box.center[1])),
        size=(float(box.size[0]), float(box.size[1]), float(box.height)),
    )
