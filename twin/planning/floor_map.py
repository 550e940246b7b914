"""A site's floor: where the robots can drive and what stands in the way, in the map's
frame, as shapely geometry."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import shapely
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry

SIMPLIFY_ABOVE = 5000
"""A free floor of more vertices than this (a SLAM map's ragged walls) is simplified before
it is shrunk: GEOS takes minutes to shrink 30,000 vertices, a second or less after."""

SIMPLIFY = 0.05
"""Tolerance of that simplification, m (a SLAM map's cell): the shrinking takes it off
too, so the reachable floor stays inside the exact one, at most this much smaller."""


class MapError(ValueError):
    """A map that cannot be used: the message names the file, the element (a layer, a
    pixel value, a camera) and what was expected.

    Attributes:
        file: the map file (or ``"<map>"``).
    """

    def __init__(self, file: str | Path, message: str) -> None:
        self.file = str(file)
        super().__init__(f"{self.file}: {message}")


@dataclass(frozen=True)
class MapObstacle:
    """Something that stands on the floor: a wall, a pillar, a counter.

    Attributes:
        footprint: its outline on the floor, map frame, m.
        height: how high it stands above the floor, m (``math.inf`` for walls that reach
            the ceiling).
        name: where it came from (a DXF layer, ``occupied`` cells, a mesh's section).
    """

    footprint: Polygon
    height: float = math.inf
    name: str = "obstacle"


@dataclass(frozen=True)
class FloorMap:
    """A site's floor in the map's frame (x, y in m, z up from the floor).

    Attributes:
        free: the floor the robots may drive on (the robots' own clearance not yet taken
            off), a Polygon or MultiPolygon.
        obstacles: what stands on the floor, with heights (for lines of sight).
        height: the ceiling's height above the floor, m.
        source: the file it was read from.
        options: the reader's keyword options it was read with (:func:`twin.planning.maps.
            load_map`'s), so that the same floor can be read again.
        height_known: whether ``height`` is the map's own (a mesh's top, or one the reader
            was given) rather than a default.
    """

    free: Polygon | MultiPolygon
    obstacles: tuple[MapObstacle, ...] = ()
    height: float = 3.0
    source: str = "<map>"
    notes: tuple[str, ...] = field(default=())
    options: dict[str, Any] = field(default_factory=dict)
    height_known: bool = False
    _reachable: dict[float, BaseGeometry] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(min x, min y, max x, max y) of the free floor, m."""
        return self.free.bounds

    def reachable(self, clearance: float) -> BaseGeometry:
        """Where a robot's centre may be with ``clearance`` m from everything (the free
        floor shrunk by it), kept for the next call. A floor of more than
        :data:`SIMPLIFY_ABOVE` vertices is first simplified by :data:`SIMPLIFY` and shrunk
        by that much more (a subset of the exact answer)."""
        key = float(clearance)
        if key not in self._reachable:
            free, extra = self.free, 0.0
            if shapely.get_num_coordinates(free) > SIMPLIFY_ABOVE:
                free, extra = free.simplify(SIMPLIFY, preserve_topology=True), SIMPLIFY
            self._reachable[key] = free.buffer(-(key + extra))
        return self._reachable[key]
