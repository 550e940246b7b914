"""Reading the maps users have into a :class:`~twin.planning.floor_map.FloorMap`.

:func:`load_map` picks the reader by the file's extension:

- ``.yaml`` / ``.yml``: a ROS occupancy grid (map_server's YAML and its PGM/PNG image),
  :func:`twin.planning.ros_map.load_ros_map`;
- ``.dxf``: a CAD floor plan, :func:`twin.planning.dxf_map.load_dxf_map`;
- ``.obj``, ``.stl``, ``.ply``, ``.gltf``, ``.glb``: a building mesh,
  :func:`twin.planning.mesh_map.load_mesh_map`.

Every reader returns the free floor in the map's own frame (x, y in m; the DXF's or the
mesh's x-y plane, the ROS map frame), the obstacles standing on it with heights above the
floor (m, ``math.inf`` where the map has no heights), and notes on what was left out.

What the readers share (unit names, picking the regions of free floor to keep) is in
:mod:`twin.planning.map_reading`; this module re-exports it.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from twin.planning.floor_map import FloorMap, MapError
from twin.planning.map_reading import (
    KEEP_CHOICES,
    UNIT_NAMES,
    check_keep,
    enclosed_regions,
    polygons_of,
    select_regions,
    unit_scale,
)

__all__ = [
    "KEEP_CHOICES",
    "MAP_SUFFIXES",
    "UNIT_NAMES",
    "check_keep",
    "enclosed_regions",
    "load_map",
    "polygons_of",
    "select_regions",
    "unit_scale",
]

#: The extensions :func:`load_map` reads, and the kind of map each is.
MAP_SUFFIXES: dict[str, str] = {
    ".yaml": "ros",
    ".yml": "ros",
    ".dxf": "dxf",
    ".obj": "mesh",
    ".stl": "mesh",
    ".ply": "mesh",
    ".gltf": "mesh",
    ".glb": "mesh",
}


def load_map(path: str | Path, **options: Any) -> FloorMap:
    """Read a site's map into a :class:`FloorMap`, choosing the reader by extension.

    Args:
        path: a ROS map YAML (``.yaml``/``.yml``), a DXF floor plan (``.dxf``) or a
            building mesh (``.obj``, ``.stl``, ``.ply``, ``.gltf``, ``.glb``).
        **options: passed on to the reader: see
            :func:`~twin.planning.ros_map.load_ros_map`,
            :func:`~twin.planning.dxf_map.load_dxf_map` and
            :func:`~twin.planning.mesh_map.load_mesh_map`.

    Returns:
        The free floor and the obstacles in the map's frame, m, with ``options`` kept.

    Raises:
        MapError: an extension none of the readers knows, or a map the reader rejects.
        TypeError: an option the chosen reader does not take.
    """
    path = Path(path)
    kind = MAP_SUFFIXES.get(path.suffix.lower())
    if kind == "ros":
        from twin.planning.ros_map import load_ros_map

        return dataclasses.replace(load_ros_map(path, **options), options=dict(options))
    if kind == "dxf":
        from twin.planning.dxf_map import load_dxf_map

        return dataclasses.replace(load_dxf_map(path, **options), options=dict(options))
    if kind == "mesh":
        from twin.planning.mesh_map import load_mesh_map

        return dataclasses.replace(load_mesh_map(path, **options), options=dict(options))
    raise MapError(
        path,
        f"unknown map type {path.suffix or '(no extension)'!r}: expected one of "
        f"{', '.join(sorted(MAP_SUFFIXES))}",
    )
