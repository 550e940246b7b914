"""Where on a map the robots can go from the start, and where the group starts.

The floor the parent reaches with its clearance falls into pieces (a room behind a door
narrower than the robots, a pocket a SLAM map closes off). A camera belongs to the piece
that holds most of its floor view; the plan keeps to one piece, the start's (by default the
piece most cameras belong to), and names every camera of the others with why: its view is
on a separate piece of floor, or beyond a passage narrower than the robots need, or on
floor too narrow for them.

The group starts where the parent and both children fit: the children stand 1.2 to 2.7 m
from the parent, clear of walls, in plain sight of it.

Everything is in the map's frame (x, y in m) unless said otherwise.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import shapely
from numpy.typing import ArrayLike, NDArray
from shapely.geometry import LineString, Point, Polygon
from shapely.geometry.base import BaseGeometry

from twin.planning.floor_map import FloorMap
from twin.planning.map_reading import polygons_of
from twin.scenario.robots import PIONEER3DX

__all__ = [
    "CHILD_CLEARANCE",
    "CHILD_OFFSETS",
    "children_at",
    "floor_pieces",
    "group_start",
    "main_piece",
    "piece_at",
    "unreachable_why",
    "view_counts",
]

CHILD_CLEARANCE = PIONEER3DX.radius + 0.1
"""Clearance a child's start keeps from everything, m."""

CHILD_OFFSETS = ((1.5, 1.5), (1.5, -1.5), (-1.5, 1.5), (-1.5, -1.5), (2.5, 1.0), (2.5, -1.0))
"""Where the children start first, (x, y) m from the parent in W (its heading along x)."""

CHILD_RING = ((2.0, 1.5, 2.5, 1.2), 30.0)
"""Then anywhere on rings round the parent: their radii, m, and the angle between two
places on a ring, degrees."""

CHILDREN_APART = 1.0
"""Least distance between the two children's starts, m."""

START_SPACING = 0.25
"""Spacing of the places tried for a start, m."""

START_TRIES = 4000
"""How many places, nearest first, are tried for a start."""


def floor_pieces(reachable: BaseGeometry) -> list[Polygon]:
    """The connected pieces of the floor the parent reaches, largest first."""
    return sorted(polygons_of(reachable), key=lambda p: p.area, reverse=True)


def piece_at(pieces: Sequence[Polygon], xy: ArrayLike) -> int | None:
    """The index of the piece holding ``xy``, or None."""
    point = Point(*np.asarray(xy, dtype=float)[:2])
    for k, piece in enumerate(pieces):
        if piece.covers(point):
            return k
    return None


def view_counts(
    pieces: Sequence[Polygon], views: Mapping[str, NDArray], clearance: float
) -> dict[str, NDArray[np.int64]]:
    """How many of each camera's floor-view points each piece holds (within ``clearance``
    of it: the parent's body covers that far).

    Args:
        pieces: the floor pieces. views: (N, 2) each camera's floor-view points on the free
            floor, by name. clearance: the parent's clearance, m.

    Returns:
        (P,) counts per piece, by camera name.
    """
    out = {name: np.zeros(len(pieces), dtype=np.int64) for name in views}
    if not pieces:
        return out
    tree = shapely.STRtree(pieces)
    for name, pts in views.items():
        if len(pts) == 0:
            continue
        pairs = tree.query(shapely.points(pts), predicate="dwithin", distance=clearance + 0.05)
        out[name] = np.bincount(pairs[1], minlength=len(pieces)).astype(np.int64)
    return out


def main_piece(pieces: Sequence[Polygon], counts: Mapping[str, NDArray]) -> int:
    """The piece most cameras belong to (the larger on a tie)."""
    homes = np.zeros(len(pieces), dtype=np.int64)
    for c in counts.values():
        if c.sum() > 0:
            homes[int(np.argmax(c))] += 1
    return int(np.argmax(homes))  # pieces are largest first: argmax keeps the larger


def unreachable_why(
    floor: FloorMap,
    pieces: Sequence[Polygon],
    region: int,
    counts: NDArray,
    view: NDArray,
    clearance: float,
) -> str | None:
    """Why a camera's floor view cannot be reached from the piece ``region``, or None if it
    can (``region`` holds as much of the view as any piece, or the view holds no free
    floor: the station's search says what then).

    Args:
        floor: the map. pieces: the floor pieces. region: the start's piece.
        counts: (P,) the camera's view points each piece holds. view: (N, 2) its view
            points on the free floor. clearance: the parent's clearance, m.
    """
    if len(view) == 0:
        return None
    need = 2 * clearance
    if counts.sum() == 0:
        x, y = view.mean(axis=0)
        return (
            f"its floor view lies on floor narrower than the robots need ({need:.2f} m) "
            f"around ({x:.2f}, {y:.2f})"
        )
    if counts[region] >= counts.max():
        return None
    home = int(np.argmax(counts))
    raw = polygons_of(floor.free)
    inner = pieces[home].representative_point()
    own = next((p for p in raw if p.covers(inner)), None)
    start_side = pieces[region].representative_point()
    if own is None or not own.covers(start_side):
        piece = own if own is not None else pieces[home]
        c = piece.centroid if piece.covers(piece.centroid) else piece.representative_point()
        return (
            f"its floor view falls on a separate piece of floor, {piece.area:.1f} m^2 around "
            f"({c.x:.2f}, {c.y:.2f}), that no floor joins to the start's"
        )
    line = shapely.shortest_line(pieces[region], pieces[home])
    mid = line.interpolate(0.5, normalized=True)
    (x0, y0), (x1, y1) = line.coords
    if own.covers(mid):
        width = 2 * own.exterior.distance(mid)
        width = min([width, *(2 * Polygon(r).exterior.distance(mid) for r in own.interiors)])
        return (
            f"its floor view lies beyond a passage {width:.2f} m wide at ({mid.x:.2f}, "
            f"{mid.y:.2f}), narrower than the {need:.2f} m the robots need"
        )
    return (
        f"its floor view lies beyond a passage narrower than the {need:.2f} m the robots need, "
        f"between ({x0:.2f}, {y0:.2f}) and ({x1:.2f}, {y1:.2f})"
    )


def children_at(
    child_free: BaseGeometry, xy: ArrayLike, yaw: float
) -> list[NDArray[np.float64]] | None:
    """The children's starts beside a parent starting at ``xy`` heading ``yaw``: the first
    two of :data:`CHILD_OFFSETS`, then of :data:`CHILD_RING`, that stand on
    ``child_free`` in plain sight of the parent and :data:`CHILDREN_APART` apart.

    Args:
        child_free: where a child's centre may stand, map frame.
        xy: the parent's start, map frame, m. yaw: its heading, rad.

    Returns:
        The two starts in W (the parent's frame at its start), m; None if no two fit.
    """
    origin = np.asarray(xy, dtype=float)[:2]
    c, s = math.cos(yaw), math.sin(yaw)
    out: list[NDArray[np.float64]] = []
    for offset in _offsets():
        turned = np.array([c * offset[0] - s * offset[1], s * offset[0] + c * offset[1]])
        place = origin + turned
        if not child_free.covers(LineString([origin, place])):
            continue
        if all(np.linalg.norm(offset - o) >= CHILDREN_APART for o in out):
            out.append(offset)
        if len(out) == 2:
            return out
    return None


def _offsets() -> list[NDArray[np.float64]]:
    out = [np.asarray(o, dtype=float) for o in CHILD_OFFSETS]
    radii, step = CHILD_RING
    for r in radii:
        for a in np.radians(np.arange(0.0, 360.0, step)):
            out.append(np.array([r * math.cos(a), r * math.sin(a)]))
    return out


def group_start(
    region: BaseGeometry,
    child_free: BaseGeometry,
    near: ArrayLike,
    yaw: float = 0.0,
    spacing: float = START_SPACING,
    tries: int = START_TRIES,
) -> tuple[float, float] | None:
    """The place of ``region`` nearest ``near`` (on a grid of ``spacing`` m, ``near``
    itself first) where the parent and both children fit heading ``yaw``; None if none of
    the ``tries`` nearest does.

    Args:
        region: where the parent's start may be, map frame. child_free: where a child's
            centre may stand. near: (2,) m. yaw: rad.
    """
    near = np.asarray(near, dtype=float)[:2]
    shapely.prepare(child_free)
    x0, y0, x1, y1 = region.bounds
    xs = np.arange(x0, x1 + spacing, spacing)
    ys = np.arange(y0, y1 + spacing, spacing)
    gx, gy = np.meshgrid(xs, ys)
    pts = np.vstack([near, np.column_stack([gx.ravel(), gy.ravel()])])
    shapely.prepare(region)
    pts = pts[shapely.contains_xy(region, pts[:, 0], pts[:, 1])]
    order = np.argsort(np.linalg.norm(pts - near, axis=1), kind="stable")
    pts = pts[order[:tries]]
    for p in pts:
        if children_at(child_free, p, yaw) is not None:
            return float(p[0]), float(p[1])
    return None
