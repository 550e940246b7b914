"""Generated floors of the shapes real buildings are hard at: a corridor turning by any
angle, a U-turn, a dead-end room off a corridor, two rooms joined by a doorway.

Each shape is the free floor as a shapely polygon in the map's frame (m), with the start of
its way in at the origin heading along +x; :func:`floor_map` makes it a
:class:`~twin.planning.floor_map.FloorMap`, :func:`write_ros_map` a ROS occupancy grid
(optionally with the flaws of a SLAM map: speckle, unknown cells, gaps in thin walls) that
``twin site`` reads as a user's map.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import shapely
import yaml
from shapely.geometry import LineString, Polygon, box

from twin.planning.floor_map import FloorMap

WALL = 0.2
"""Thickness of the walls between rooms, m."""


def _path(points: list[tuple[float, float]], width: float) -> Polygon:
    """A corridor of ``width`` m along the polyline ``points`` (m): flat ends, mitred turns
    (the outside of a turn square, as built)."""
    if width <= 0:
        raise ValueError(f"a corridor's width must be positive, got {width!r}")
    return LineString(points).buffer(0.5 * width, cap_style="flat", join_style="mitre")


def corridor_turn(width: float, turn_deg: float, leg: float = 12.0) -> Polygon:
    """A corridor ``width`` m wide, ``leg`` m straight along +x, then turning by
    ``turn_deg`` degrees (0 to 180; positive to the left) for another ``leg`` m.

    Raises:
        ValueError: a turn outside [0, 180] degrees or a corridor that would overlap itself.
    """
    if not 0.0 <= turn_deg <= 180.0:
        raise ValueError(f"a turn is 0 to 180 degrees, got {turn_deg!r}")
    if turn_deg > 135.0:
        # A hairpin: two parallel legs joined across; the legs' walls keep WALL between them.
        return u_turn(width, leg, gap=WALL)
    a = math.radians(turn_deg)
    end = (leg + leg * math.cos(a), leg * math.sin(a))
    return _path([(0.0, 0.0), (leg, 0.0), end], width)


def u_turn(width: float, leg: float = 12.0, gap: float = WALL) -> Polygon:
    """A corridor ``width`` m wide along +x for ``leg`` m that turns back on itself: the
    way back runs parallel, ``gap`` m of wall between the two."""
    pitch = width + gap
    return _path([(0.0, 0.0), (leg, 0.0), (leg, pitch), (0.0, pitch)], width)


def dead_end(
    width: float,
    length: float = 16.0,
    room: tuple[float, float] = (5.0, 4.0),
    door: float = 1.2,
) -> Polygon:
    """A corridor ``width`` m wide and ``length`` m long along +x with a room (``room``:
    its width along the corridor and depth, m) off its left side halfway, through a door
    ``door`` m wide in a wall :data:`WALL` thick; the corridor ends blind."""
    half = 0.5 * width
    corridor = box(0.0, -half, length, half)
    x = 0.5 * length
    y0 = half + WALL
    chamber = box(x - 0.5 * room[0], y0, x + 0.5 * room[0], y0 + room[1])
    opening = box(x - 0.5 * door, half - 1e-9, x + 0.5 * door, y0 + 1e-9)
    return _single(shapely.union_all([corridor, chamber, opening]))


def doorway(room: tuple[float, float] = (8.0, 6.0), door: float = 1.0) -> Polygon:
    """Two rooms of ``room`` (length along x, width, m) side by side along +x, joined by a
    door ``door`` m wide in the middle of the wall (:data:`WALL` thick) between them; the
    way in starts 1.5 m into the first room."""
    length, wide = room
    first = box(-1.5, -0.5 * wide, length - 1.5, 0.5 * wide)
    x = length - 1.5
    second = box(x + WALL, -0.5 * wide, x + WALL + length, 0.5 * wide)
    opening = box(x - 1e-9, -0.5 * door, x + WALL + 1e-9, 0.5 * door)
    return _single(shapely.union_all([first, second, opening]))


def _single(geometry: shapely.Geometry) -> Polygon:
    if not isinstance(geometry, Polygon):
        raise ValueError(f"the shape's pieces do not join into one floor: {geometry.geom_type}")
    return geometry


def floor_map(free: Polygon, height: float = 3.0, source: str = "<generated>") -> FloorMap:
    """``free`` (map frame, m) as a map whose walls reach ``height`` m."""
    return FloorMap(free=free, height=height, source=source)


def rasterise(free: Polygon, resolution: float = 0.05, margin: float = 1.0) -> tuple:
    """``free`` on a grid: (H, W) bool free cells (row 0 at the top, as a map image), and the
    (x, y) of the grid's lower-left corner, m; ``margin`` m of blocked border."""
    x0, y0, x1, y1 = free.bounds
    x0, y0 = x0 - margin, y0 - margin
    nx = math.ceil((x1 + margin - x0) / resolution)
    ny = math.ceil((y1 + margin - y0) / resolution)
    xs = x0 + (np.arange(nx) + 0.5) * resolution
    ys = y0 + (np.arange(ny)[::-1] + 0.5) * resolution
    gx, gy = np.meshgrid(xs, ys)
    return shapely.contains_xy(free, gx, gy), (x0, y0)


def slam_flaws(
    free: np.ndarray,
    rng: np.random.Generator,
    speckle: float = 0.002,
    gaps: float = 0.02,
    unknown: float = 0.3,
) -> np.ndarray:
    """A SLAM map's grid from the truth's: (H, W) uint8 cells 254 free, 0 occupied, 205
    unknown.

    Args:
        free: (H, W) bool, the true free cells.
        rng: the randomness.
        speckle: fraction of free cells read occupied (single cells: sensor noise).
        gaps: fraction of wall cells next to the free floor read free (thin walls with holes).
        unknown: fraction of the blocked cells away from the floor never seen (unknown).
    """
    out = np.where(free, 254, 0).astype(np.uint8)
    blocked = ~free
    near = cv2.dilate(free.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool) & blocked
    far = blocked & ~cv2.dilate(free.astype(np.uint8), np.ones((9, 9), np.uint8)).astype(bool)
    out[far & (rng.random(free.shape) < unknown)] = 205
    out[near & (rng.random(free.shape) < gaps)] = 254
    out[free & (rng.random(free.shape) < speckle)] = 0
    return out


def write_ros_map(
    free: Polygon,
    folder: str | Path,
    resolution: float = 0.05,
    flaws: bool = False,
    seed: int = 0,
    name: str = "map",
) -> Path:
    """Write ``free`` as ROS map-server files ``NAME.png`` and ``NAME.yaml`` in ``folder``
    (with a SLAM map's flaws, seeded, if ``flaws``); returns the YAML's path."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    cells, (x0, y0) = rasterise(free, resolution)
    image = (
        slam_flaws(cells, np.random.default_rng(seed))
        if flaws
        else np.where(cells, 254, 0).astype(np.uint8)
    )
    cv2.imwrite(str(folder / f"{name}.png"), image)
    meta = {
        "image": f"{name}.png",
        "resolution": resolution,
        "origin": [float(x0), float(y0), 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(meta, sort_keys=False))
    return path
