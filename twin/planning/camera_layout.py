"""Cameras placed on a map by a fixed rule, as an installer would hang them: along the middle
of the floor, every few metres, high up, looking down along the corridor.

The rule (:func:`place_cameras`):

1. the medial axis of the free floor, on a grid: the cells that are at least as far from
   the floor's edge as their two neighbours along some direction (the ridge of the distance
   transform), where a robot's centre fits (the robots' clearance from the edge), on every
   piece of that floor of at least 1 m^2, reachable from one start or not;
2. points on the axis at least ``spacing`` m apart, taken greedily in an order drawn from
   ``seed``; the spacing is widened or narrowed until there are ``least`` to ``most``
   cameras (as far as the floor allows);
3. each camera ``height`` m over its point, looking ``tilt_deg`` down along the axis there
   (the axis's main direction within 1.5 m), towards the side with the longer free floor;
   where neither side runs 3 m free (a stub of the axis at a junction or in an alcove),
   along the longest free line instead, never at a wall a metre away.

Nothing is chosen by hand, so no hard spot of a map (a narrow passage, a pocket cut off from
the rest) is left out. ``python -m twin.planning.camera_layout MAP --out cameras.yaml``
writes the cameras file ``twin site`` reads.
"""

from __future__ import annotations

import argparse
import logging
import math
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import shapely
import yaml
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

from twin.planning.floor_map import FloorMap
from twin.planning.site import FORMATION_CLEARANCE

_log = logging.getLogger(__name__)

HEIGHT = 3.0
"""The cameras' height above the floor, m (a ceiling camera)."""

TILT_DEG = 30.0
"""How far below the horizontal the cameras look, degrees."""

SPACING = 8.0
"""Distance between cameras along the floor's medial axis to begin with, m."""

LEAST_SPACING = 2.0
"""The spacing is not narrowed below this, m: a small floor gets fewer cameras."""

LEAST, MOST = 6, 30
"""How many cameras a site gets, as far as its floor allows."""

CLEARANCE = FORMATION_CLEARANCE
"""Clearance of a robot's centre from walls the axis is taken on, m (the parent's radius and
room for a child beside it)."""

LEAST_PIECE = 1.0
"""Pieces of reachable floor smaller than this get no camera, m^2."""

GRID = 0.1
"""Cell of the grid the axis is found on, m (coarser for floors of more than
:data:`MAX_CELLS` cells)."""

MAX_CELLS = 4_000_000

INTRINSICS: dict[str, Any] = {"f": 300.0, "cx": 159.5, "cy": 119.5, "image_size": [320, 240]}
"""Every camera's nominal intrinsics (a 320 x 240 camera, 56 degrees across)."""


def medial_axis(
    region: BaseGeometry,
    grid: float = GRID,
    clearance: float = 0.0,
    least_piece: float = 0.0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The medial axis of ``region`` on a grid, where it is ``clearance`` m clear of the
    region's edge, on pieces of that clear floor of ``least_piece`` m^2 or more.

    Args:
        region: a Polygon or MultiPolygon, m.
        grid: cell size, m (made coarser to keep to :data:`MAX_CELLS`).
        clearance: least distance of the axis from the region's edge, m.
        least_piece: pieces of the floor ``clearance`` m clear of the edge smaller than
            this are left out, m^2.

    Returns:
        ``(points, clearance)``: (N, 2) centres of the axis's cells (m, ordered by row then
        column of the grid, north first) and (N,) their distance from the region's edge, m
        (to the grid's half a cell).
    """
    x0, y0, x1, y1 = region.bounds
    grid = max(grid, math.sqrt((x1 - x0) * (y1 - y0) / MAX_CELLS))
    nx, ny = math.ceil((x1 - x0) / grid) + 2, math.ceil((y1 - y0) / grid) + 2
    xs = x0 - grid + (np.arange(nx) + 0.5) * grid
    ys = y0 - grid + (np.arange(ny)[::-1] + 0.5) * grid
    gx, gy = np.meshgrid(xs, ys)
    shapely.prepare(region)
    inside = shapely.contains_xy(region, gx, gy)
    # Distance from a cell's centre to the nearest cell outside, in cells.
    dist = cv2.distanceTransform(inside.astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    edge = (dist - 0.5) * grid
    clear = inside & (edge >= clearance)
    _, labels, stats, _ = cv2.connectedComponentsWithStats(clear.astype(np.uint8), None, 8)
    big = stats[:, cv2.CC_STAT_AREA] * grid**2 >= least_piece
    big[0] = False  # the label of the cells not clear
    clear &= big[labels]
    pad = np.pad(dist, 1)
    ridge = np.zeros_like(inside)
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        a = pad[1 + dr : 1 + dr + ny, 1 + dc : 1 + dc + nx]
        b = pad[1 - dr : 1 - dr + ny, 1 - dc : 1 - dc + nx]
        ridge |= (dist >= a) & (dist >= b) & ((dist > a) | (dist > b))
    ridge &= clear
    rows, cols = np.nonzero(ridge)
    points = np.column_stack([xs[cols], ys[rows]])
    return points, edge[rows, cols]


def _spread(points: NDArray, order: NDArray, spacing: float) -> list[int]:
    """Indices of ``points`` taken in ``order``, each at least ``spacing`` m from those
    taken before it."""
    kept: list[int] = []
    taken = np.empty((0, 2))
    for i in order:
        if taken.shape[0] == 0 or np.min(np.sum((taken - points[i]) ** 2, axis=1)) >= spacing**2:
            kept.append(int(i))
            taken = np.vstack([taken, points[i]])
    return kept


OPEN_VIEW = 3.0
"""A camera looks along the axis where the floor runs this far free that way at least, m;
else along the longest free line of 16 directions."""


def _direction(points: NDArray, at: NDArray, free: BaseGeometry) -> NDArray[np.float64]:
    """The axis's main direction near ``at`` (its points within 1.5 m), pointing to the side
    with the longer free floor (where that runs :data:`OPEN_VIEW` m free; else the direction
    of the longest free line), unit (2,)."""
    near = points[np.sum((points - at) ** 2, axis=1) <= 1.5**2] - at
    if near.shape[0] < 2:
        axis = np.array([1.0, 0.0])
    else:
        _, vecs = np.linalg.eigh(near.T @ near)
        axis = vecs[:, -1]
    reach = [_free_length(free, at, s * axis) for s in (1.0, -1.0)]
    if max(reach) >= OPEN_VIEW:
        return axis if reach[0] >= reach[1] else -axis
    # A stub of the axis (a junction, an alcove): no installer aims a camera at the wall a
    # metre away, so the camera looks the way of the longest free floor instead.
    turns = np.linspace(0.0, 2.0 * math.pi, 16, endpoint=False)
    ways = np.column_stack([np.cos(turns), np.sin(turns)])
    return ways[int(np.argmax([_free_length(free, at, w) for w in ways]))]


def _free_length(free: BaseGeometry, start: NDArray, step: NDArray, most: float = 20.0) -> float:
    """How far from ``start`` along the unit ``step`` stays on ``free``, up to ``most``, m."""
    ends = start + np.outer(np.arange(0.5, most + 0.25, 0.5), step)
    ok = shapely.contains_xy(free, ends[:, 0], ends[:, 1])
    return 0.5 * (int(np.argmin(ok)) if not ok.all() else len(ok))


def place_cameras(
    floor: FloorMap,
    *,
    seed: int = 0,
    spacing: float = SPACING,
    height: float = HEIGHT,
    tilt_deg: float = TILT_DEG,
    least: int = LEAST,
    most: int = MOST,
    clearance: float = CLEARANCE,
) -> list[dict[str, Any]]:
    """Cameras on ``floor`` by the module's rule.

    Args:
        floor: the map (map frame, m).
        seed: the order the axis's points are taken in.
        spacing: distance between cameras to begin with, m.
        height: the cameras' height above the floor, m.
        tilt_deg: how far below the horizontal they look, degrees.
        least, most: how many cameras to place (fewer where the floor has no room).
        clearance: the robots' clearance the axis is taken on, m.

    Returns:
        The cameras file's entries (``name``, ``position`` [x, y, height] in the map's
        frame, unit ``view_direction``, :data:`INTRINSICS`), named ``cam1``... in the
        order taken.

    Raises:
        ValueError: no floor a robot fits on, or ``least`` > ``most``.
    """
    if not 1 <= least <= most:
        raise ValueError(f"expected 1 <= least <= most, got least={least}, most={most}")
    points, _ = medial_axis(floor.free, clearance=clearance, least_piece=LEAST_PIECE)
    if points.shape[0] == 0:
        raise ValueError(f"{floor.source}: no floor is {clearance:g} m clear of the walls")
    order = np.random.default_rng(seed).permutation(points.shape[0])
    kept = _spread(points, order, spacing)
    for _ in range(30):
        if len(kept) > most:
            spacing *= 1.05 * math.sqrt(len(kept) / most)
        elif len(kept) < least and spacing > LEAST_SPACING:
            spacing = max(LEAST_SPACING, spacing * 0.95 * math.sqrt(len(kept) / least))
        else:
            break
        kept = _spread(points, order, spacing)
    kept = kept[:most]
    shapely.prepare(floor.free)
    tilt = math.radians(tilt_deg)
    cameras = []
    for k, i in enumerate(kept):
        at = points[i]
        d = _direction(points, at, floor.free)
        view = [math.cos(tilt) * d[0], math.cos(tilt) * d[1], -math.sin(tilt)]
        cameras.append(
            {
                "name": f"cam{k + 1}",
                "position": [round(float(at[0]), 3), round(float(at[1]), 3), float(height)],
                "view_direction": [round(float(v), 6) for v in view],
                **INTRINSICS,
            }
        )
    return cameras


def write_cameras(cameras: list[dict[str, Any]], path: str | Path, header: str = "") -> Path:
    """Write ``cameras`` as the YAML cameras file ``twin site`` reads; returns its path."""
    path = Path(path)
    text = yaml.safe_dump(cameras, sort_keys=False, default_flow_style=None)
    path.write_text("".join(f"# {line}\n" for line in header.splitlines()) + text)
    return path


def main(argv: list[str] | None = None) -> int:
    from twin.planning.maps import load_map

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("map", type=Path, help="a map load_map reads (map.yaml, .dxf, mesh)")
    parser.add_argument("--out", type=Path, required=True, help="cameras file to write (.yaml)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    cameras = place_cameras(load_map(args.map), seed=args.seed)
    write_cameras(cameras, args.out, f"{len(cameras)} cameras on {args.map}, seed {args.seed}")
    _log.info("wrote %d cameras to %s", len(cameras), args.out)
    return 0


if __name__ == "__main__":
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    raise SystemExit(main())
