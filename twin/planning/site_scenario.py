"""The scenario a site plan writes: the planned room, cameras, robots, route and visits as
an ordinary scenario mapping, with ``[space.map]`` (the map referenced by its hash, not its
boxes) and ``[site]`` (the map and the map-to-W transform)."""

from __future__ import annotations

import math
from typing import Any

from numpy.typing import NDArray

from twin.planning.boxes import BoxedSpace
from twin.planning.floor_map import FloorMap
from twin.planning.frames import MapPose
from twin.planning.map_files import map_sha256
from twin.planning.site_start import START_PRISM_SIGHT


def _space_dict(space: BoxedSpace, floor_z: float, map_ref: dict[str, Any]) -> dict[str, Any]:
    """The scenario's space: the room, and the map its boxes are rebuilt from
    (``[space.map]``, :class:`twin.scenario.schema.SpaceMap`)."""
    return {
        "size": list(space.size),
        "origin": list(space.origin),
        "floor_z": floor_z,
        "map": map_ref,
    }


def map_reference(
    floor: FloorMap, map_file: str, pose: MapPose, resolution: float
) -> dict[str, Any]:
    """``[space.map]``: the map as the scenario names it, its content's hash, W's pose in it,
    the grid and the reader's options."""
    options = {
        k: list(v) if isinstance(v, (list, tuple, set)) else v for k, v in floor.options.items()
    }
    return {
        "file": map_file,
        "sha256": map_sha256(floor.source),
        "pose": [pose.x, pose.y, math.degrees(pose.yaw)],
        "resolution": resolution,
        "options": options,
    }


def scenario_dict(
    *,
    name: str,
    seed: int,
    space: BoxedSpace,
    map_ref: dict[str, Any],
    floor_z: float,
    cameras: list[dict[str, Any]],
    children: list[NDArray],
    route: NDArray,
    return_to_start: bool,
    start_prism: NDArray | None,
    visits: list[tuple[str, NDArray, float]],
    site: dict[str, Any],
    min_visible: float | None = None,
) -> dict[str, Any]:
    """The scenario as a mapping (TOML-ready, checked by the scenario loader).

    Args:
        name, seed: the scenario's. space: the room and its boxes in W (only the room is
            written: the boxes are rebuilt from ``map_ref``, :func:`map_reference`).
        floor_z: the floor's height in W, m. cameras: the scenario's camera tables, W.
        children: the children's (2,) starts in W, m. route: (K, 2) the parent's
            waypoints in W, m. return_to_start: whether the route ends at the start.
        start_prism: (2,) the prism left near the start in W, m (None: none).
        visits: (camera, (2,) station in W m, arrival heading deg) in order.
        site: ``[site]``: the map, W's pose in it, the grid.
        min_visible: ``calibration.min_visible_fraction`` (None: the scenario's default).
    """
    controls = (
        []
        if start_prism is None
        else [
            {
                "name": "start_prism",
                "position": [float(start_prism[0]), float(start_prism[1]), 0.0],
                "sight_radius_m": START_PRISM_SIGHT,
            }
        ]
    )
    return {
        "name": name,
        "description": f"Planned from the map {site['map']}: {len(cameras)} cameras.",
        "seed": seed,
        "space": _space_dict(space, floor_z, map_ref),
        "cameras": cameras,
        "robots": {
            "parent": {"name": "parent", "model": "pioneer3at", "start_xy": [0.0, 0.0]},
            "children": [
                {"name": f"child{k + 1}", "model": "pioneer3dx", "start_xy": c.tolist()}
                for k, c in enumerate(children)
            ],
        },
        "route": {"waypoints": route.tolist(), "return_to_start": return_to_start},
        "control_points": controls,
        "calibration": {
            "visits": [
                {"camera": cam, "station": xy.tolist(), "yaw_deg": heading}
                for cam, xy, heading in visits
            ],
            **({} if min_visible is None else {"min_visible_fraction": min_visible}),
        },
        "site": site,
    }
