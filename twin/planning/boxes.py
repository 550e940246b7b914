"""A floor map as the scenario's space: a rectangular room whose blocked parts are boxes.

Every fidelity (MuJoCo's world, the geometric checks, the batch fidelity, the environment)
reads a scenario's space as a rectangle with box obstacles. A map's floor, in W, is laid on
a grid; every blocked cell (outside the free floor: walls, obstacles, the unknown) becomes
part of an axis-aligned box, cells of one height merged into rectangles, each box as high
as the tallest obstacle over it (the ceiling for walls and for the unknown).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from numpy.typing import NDArray

from twin.planning.floor_map import FloorMap
from twin.planning.frames import MapPose

DEFAULT_RESOLUTION = 0.1
"""Grid of the blocked cells, m: the boxes' edges lie within half of it of the map's."""

MARGIN = 0.05
"""Room kept around the free floor inside the room's walls, m."""


@dataclass(frozen=True)
class Box:
    """One blocked rectangle in W: ``center`` (x, y) m, ``size`` (x, y) m, ``height`` m."""

    center: tuple[float, float]
    size: tuple[float, float]
    height: float


@dataclass(frozen=True)
class BoxedSpace:
    """The space of a scenario made from a map.

    Attributes:
        origin: (x, y) of the room's inner corner with the smallest x and y in W, m.
        size: (x, y, z) the room's inner extent, m.
        boxes: the blocked rectangles.
        resolution: the grid, m.
    """

    origin: tuple[float, float]
    size: tuple[float, float, float]
    boxes: tuple[Box, ...]
    resolution: float


def boxed_space(
    floor: FloorMap, pose: MapPose, resolution: float = DEFAULT_RESOLUTION
) -> BoxedSpace:
    """The room and its blocked boxes in W of ``floor`` seen from ``pose`` (as many as the
    floor needs: a scenario references its map rather than holding them)."""
    if not (math.isfinite(resolution) and resolution > 0):
        raise ValueError(f"resolution must be a positive length, got {resolution!r}")
    free = pose.geometry2world(floor.free)
    x0, y0, x1, y1 = free.bounds
    x0, y0, x1, y1 = x0 - MARGIN, y0 - MARGIN, x1 + MARGIN, y1 + MARGIN
    nx = max(1, math.ceil((x1 - x0) / resolution))
    ny = max(1, math.ceil((y1 - y0) / resolution))
    xs = x0 + (np.arange(nx) + 0.5) * resolution
    ys = y0 + (np.arange(ny) + 0.5) * resolution
    gx, gy = np.meshgrid(xs, ys)  # (ny, nx)
    blocked = ~shapely.contains_xy(free, gx, gy)
    # Cells of a low obstacle are as high as the tallest low obstacle over them; every
    # other blocked cell (walls, the unknown, the outside) reaches the ceiling.
    low = np.zeros(blocked.shape)
    covered = np.zeros(blocked.shape, dtype=bool)
    for ob in floor.obstacles:
        if not math.isfinite(ob.height):
            continue
        inside = shapely.intersects_xy(pose.geometry2world(ob.footprint), gx, gy) & blocked
        low = np.where(inside, np.maximum(low, ob.height), low)
        covered |= inside
    ceiling = float(floor.height)
    height = np.where(blocked, np.where(covered, np.minimum(low, ceiling), ceiling), 0.0)
    boxes: list[Box] = []
    for h in np.unique(height[blocked]):
        for r0, r1, c0, c1 in _rectangles(blocked & (height == h)):
            boxes.append(
                Box(
                    center=(x0 + 0.5 * (c0 + c1) * resolution, y0 + 0.5 * (r0 + r1) * resolution),
                    size=((c1 - c0) * resolution, (r1 - r0) * resolution),
                    height=float(h),
                )
            )
    size = (nx * resolution, ny * resolution, float(floor.height))
    return BoxedSpace(origin=(x0, y0), size=size, boxes=tuple(boxes), resolution=resolution)


def _rectangles(mask: NDArray[np.bool_]) -> list[tuple[int, int, int, int]]:
    """Rectangles (row0, row1, col0, col1), ends exclusive, that tile ``mask``'s True cells:
    each row's runs, merged with the same run of the rows below."""
    out: list[tuple[int, int, int, int]] = []
    open_: dict[tuple[int, int], int] = {}  # (col0, col1) -> first row
    for r in range(mask.shape[0] + 1):
        runs: set[tuple[int, int]] = set()
        if r < mask.shape[0]:
            row = np.concatenate([[False], mask[r], [False]]).astype(np.int8)
            edges = np.flatnonzero(np.diff(row))
            runs = {(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)}
        for run in list(open_):
            if run not in runs:
                out.append((open_.pop(run), r, run[0], run[1]))
        for run in runs:
            open_.setdefault(run, r)
    return out
