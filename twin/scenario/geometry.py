"""Plan geometry of a scenario, without MuJoCo: obstacles' footprints as shapely polygons,
camera views on the floor, segment tests. Used to validate scenarios, to summarise them and
to plan the campaign.

Obstacles are treated as their bounding boxes (stairs included), which is conservative
for lines of sight. The 2D tests are shapely's: points in footprints, segments across them
(:func:`segment_blocked` tests a box's height only for a segment that passes over or
under it). :func:`floor_view` (rays cast onto the floor) stays numpy: it is 3D. So does
:func:`inside_space`: the walls are an axis-aligned rectangle, and its four comparisons are
quicker than shapely's test of a point in a polygon.
"""

from __future__ import annotations

import collections
import functools
import math
import threading
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely
from numpy.typing import ArrayLike, NDArray
from shapely import affinity

from calib.camera import TsaiCamera
from twin.scenario.schema import Obstacle, Space

BROADCAST_PAIRS = 256
"""Up to this many (obstacle, point) pairs, every footprint is tested against every point;
beyond, only the points within a footprint's bounding box are (numpy is quicker at those
comparisons than shapely at its predicate, and the predicate needs only the few in it)."""


def rectangle(center: ArrayLike, size: ArrayLike, yaw: float = 0.0) -> shapely.Polygon:
    """A rectangle of (length, width) ``size`` (m) turned by ``yaw`` (rad) about its (2,)
    ``center`` (m), as a polygon."""
    return _rectangle(center, 0.5 * float(size[0]), 0.5 * float(size[1]), yaw)


def _rectangle(center: ArrayLike, hx: float, hy: float, yaw: float) -> shapely.Polygon:
    """:func:`rectangle` of half sides ``hx``, ``hy`` (m); empty if one is negative."""
    if hx < 0.0 or hy < 0.0:
        return shapely.Polygon()
    c, s = math.cos(yaw), math.sin(yaw)
    x, y = float(center[0]), float(center[1])
    return affinity.affine_transform(shapely.box(-hx, -hy, hx, hy), [c, -s, s, c, x, y])


def _footprint(obstacle: Obstacle, margin: float, center: ArrayLike) -> shapely.Polygon:
    """The obstacle's footprint grown by ``margin`` (m) on every side (a rectangle still, not
    rounded at the corners) with its centre at (2,) ``center``, m."""
    hx, hy = 0.5 * obstacle.size[0] + margin, 0.5 * obstacle.size[1] + margin
    return _rectangle(center, hx, hy, obstacle.yaw)


@dataclass(frozen=True)
class _Footprints:
    """Obstacles' footprints grown by a margin, about their centres: (O, 2) the centres in
    W, m; (O,) prepared polygons and (O, 4) their bounding boxes (xmin, ymin, xmax, ymax)
    relative to the centres, m."""

    centres: NDArray[np.float64]
    polygons: NDArray[np.object_]
    bounds: NDArray[np.float64]


_RECENT: collections.OrderedDict[int, tuple[tuple[Obstacle, ...], dict]] = collections.OrderedDict()
_RECENT_LOCK = threading.Lock()
_RECENT_SIZE = 16


def _kept(obstacles: tuple[Obstacle, ...], what: str, margin: float, make: Any) -> Any:
    """``make(obstacles, margin, thread)`` for this thread, kept for the very tuple
    ``obstacles`` (of the last few used): a space's obstacles are asked for again and
    again, and hashing thousands of them for a cache costs more than what it keeps."""
    thread = threading.get_ident()
    with _RECENT_LOCK:
        entry = _RECENT.get(id(obstacles))
        if entry is None or entry[0] is not obstacles:
            entry = (obstacles, {})
            _RECENT[id(obstacles)] = entry
            while len(_RECENT) > _RECENT_SIZE:
                _RECENT.popitem(last=False)
        _RECENT.move_to_end(id(obstacles))
    key = (what, margin, thread)
    if key not in entry[1]:
        entry[1][key] = make(obstacles, margin, thread)
    return entry[1][key]


@functools.lru_cache(maxsize=1024)
def _footprints(obstacles: tuple[Obstacle, ...], margin: float, thread: int) -> _Footprints:
    """The footprints of ``obstacles`` grown by ``margin`` (m) about their centres, for one
    ``thread`` (a prepared polygon builds its index when first asked, which threads must
    not do at once)."""
    n = len(obstacles)
    centres = np.array([ob.center for ob in obstacles], dtype=float).reshape(n, 2)
    polygons = np.empty(n, dtype=object)
    polygons[:] = [_footprint(ob, margin, (0.0, 0.0)) for ob in obstacles]
    shapely.prepare(polygons)
    bounds = shapely.bounds(polygons).reshape(n, 4)
    for a in (centres, polygons, bounds):
        a.flags.writeable = False
    return _Footprints(centres, polygons, bounds)


TREE_PAIRS = 100_000
"""Above this many (obstacle, point) pairs, :func:`inside_obstacles` finds the pairs whose
bounding boxes meet in a search tree rather than comparing every pair."""

NEAR_TOLERANCE = 1e-6
""":func:`obstacles_near` grows the points' bounding box by this much, m: far more than the
footprints' corners are rounded by, far less than anything built."""


@functools.lru_cache(maxsize=64)
def _footprint_tree(obstacles: tuple[Obstacle, ...], margin: float, thread: int) -> shapely.STRtree:
    """A search tree over the footprints of ``obstacles`` grown by ``margin`` (m), in W,
    prepared, for one ``thread`` (see :func:`_footprints`)."""
    feet = np.empty(len(obstacles), dtype=object)
    feet[:] = [_footprint(ob, margin, ob.center) for ob in obstacles]
    shapely.prepare(feet)
    return shapely.STRtree(feet)


def inside_obstacles(
    obstacles: tuple[Obstacle, ...], points_xy: ArrayLike, margin: float = 0.0
) -> NDArray[np.bool_]:
    """(O, N) True where (N, 2) floor points (m) lie in each of the O obstacles' footprints
    grown by ``margin`` (m) on every side, their boundaries included.

    The points are moved to each footprint's centre before shapely tests them: a side of an
    axis-aligned footprint then lies, to the bit, where ``|point - centre| <= half side``
    puts it (points at exactly a clearance from a wall or an obstacle are common, and a
    footprint placed in W rounds its sides differently).
    """
    p = np.array(points_xy, dtype=float, ndmin=2)
    obstacles = tuple(obstacles)
    feet = _kept(obstacles, "feet", float(margin), _footprints)
    if len(obstacles) * len(p) > TREE_PAIRS:
        # The pairs whose bounding boxes meet, from the search tree, then the same tests.
        tree = _kept(obstacles, "tree", float(margin), _footprint_tree)
        tol = NEAR_TOLERANCE
        x, y = p[:, 0], p[:, 1]
        pt, ob = tree.query(shapely.box(x - tol, y - tol, x + tol, y + tol))
        dx = p[pt, 0] - feet.centres[ob, 0]
        dy = p[pt, 1] - feet.centres[ob, 1]
        b = feet.bounds[ob]
        near = (dx >= b[:, 0]) & (dy >= b[:, 1]) & (dx <= b[:, 2]) & (dy <= b[:, 3])
        pt, ob, dx, dy = pt[near], ob[near], dx[near], dy[near]
        inside = np.zeros((len(obstacles), len(p)), dtype=bool)
        inside[ob, pt] = shapely.intersects_xy(feet.polygons[ob], dx, dy)
        return inside
    dx = np.ascontiguousarray(p[:, 0]) - feet.centres[:, :1]
    dy = np.ascontiguousarray(p[:, 1]) - feet.centres[:, 1:]
    if dx.size <= BROADCAST_PAIRS:
        return shapely.intersects_xy(feet.polygons[:, None], dx, dy)
    b = feet.bounds
    inside = (dx >= b[:, :1]) & (dy >= b[:, 1:2]) & (dx <= b[:, 2:3]) & (dy <= b[:, 3:])
    flat = inside.reshape(-1)
    k = np.flatnonzero(flat)
    flat[k] = shapely.intersects_xy(feet.polygons[k // len(p)], dx.flat[k], dy.flat[k])
    return inside


def obstacles_near(
    obstacles: tuple[Obstacle, ...], points_xy: ArrayLike, margin: float = 0.0
) -> tuple[Obstacle, ...]:
    """The obstacles whose footprint grown by ``margin`` (m) reaches the bounding box of
    (N, 2) floor points (m) grown by :data:`NEAR_TOLERANCE`: the only ones that can hold one
    of the points within ``margin`` or block a segment between two of them. One query of a
    search tree, which spares the exact tests most obstacles of a large space."""
    p = np.array(points_xy, dtype=float, ndmin=2)
    if not obstacles or not p.size:
        return ()
    obstacles = tuple(obstacles)
    x, y = p[:, 0], p[:, 1]
    tol = NEAR_TOLERANCE
    span = shapely.box(x.min() - tol, y.min() - tol, x.max() + tol, y.max() + tol)
    tree = _kept(obstacles, "tree", float(margin), _footprint_tree)
    near = tree.query(span, predicate="intersects")
    return tuple(obstacles[k] for k in np.sort(near))


def inside_space(space: Space, points_xy: ArrayLike, margin: float = 0.0) -> NDArray[np.bool_]:
    """(N,) True where (N, 2) points (m) lie inside the walls, at least ``margin`` (m) from
    them."""
    p = np.array(points_xy, dtype=float, ndmin=2)
    (x0, x1), (y0, y1) = space.x_range, space.y_range
    return (
        (p[:, 0] >= x0 + margin)
        & (p[:, 0] <= x1 - margin)
        & (p[:, 1] >= y0 + margin)
        & (p[:, 1] <= y1 - margin)
    )


def _box_arrays(
    floor_z: float, obs: tuple[Obstacle, ...], margin: float = 0.0
) -> tuple[NDArray, ...]:
    """The boxes of ``obs`` standing on a floor at ``floor_z`` (m) as arrays: (O, 2)
    centres, (O,) cos and sin of their yaws, and (O, 3) lowest and highest corners in their
    own frames (origin at the footprint's centre, axes along its sides, z unchanged), m; the
    sides and the top moved out by ``margin``, m."""
    centre = np.array([ob.center for ob in obs], dtype=float).reshape(-1, 2)
    yaw = [ob.yaw for ob in obs]
    c = np.array([np.cos(y) for y in yaw])
    s = np.array([np.sin(y) for y in yaw])
    size = np.array([ob.size for ob in obs], dtype=float).reshape(-1, 3)
    half = 0.5 * size[:, :2] + margin
    lo = np.column_stack([-half, np.full(len(obs), floor_z)])
    hi = np.column_stack([half, floor_z + size[:, 2] + margin])
    return centre, c, s, lo, hi


def segment_blocked(
    space: Space,
    starts: ArrayLike,
    ends: ArrayLike,
    obstacles: tuple[Obstacle, ...] = (),
    margin: float = 0.0,
) -> NDArray[np.bool_]:
    """(N,) True where the 3D segment from starts[i] to ends[i] crosses an obstacle's box,
    its faces included.

    Where a segment runs between a box's floor and top along its whole length, the test is
    2D: whether the segment's plan meets the footprint (shapely's predicate on the
    footprints placed in W). Only the boxes a segment passes over or under need their
    height: the slab test, in the box's own frame. Both for the pairs a search tree of the
    footprints finds, all segments at once.

    Args:
        space: gives the floor height (obstacles stand on the floor).
        starts, ends: (N, 3) world points, m.
        obstacles: the boxes to test (default: all of the space's obstacles).
        margin: pass at least this far from every box's sides and top, m.
    """
    a = np.array(starts, dtype=float, ndmin=2)
    b = np.array(ends, dtype=float, ndmin=2)
    a, b = np.broadcast_arrays(a, b)
    obs = tuple(obstacles) or space.obstacles
    blocked = np.zeros(len(a), dtype=bool)
    if not obs or not len(a):
        return blocked
    centre, c, s, lo, hi = _kept(
        obs, f"boxes {space.floor_z!r}", float(margin), _boxes_of(space.floor_z)
    )
    lines = shapely.linestrings(np.stack([a[:, :2], b[:, :2]], axis=1))
    # The pairs whose plans may meet: the footprints grown by NEAR_TOLERANCE (the slab
    # test and the footprint placed in W round a side differently).
    tree = _kept(obs, "grown tree", float(margin), _grown_tree)
    seg, ob = tree.query(lines, predicate="intersects")
    low = np.minimum(a[seg, 2], b[seg, 2])
    high = np.maximum(a[seg, 2], b[seg, 2])
    tall = (lo[ob, 2] <= low) & (hi[ob, 2] >= high)
    feet = _kept(obs, "tree", float(margin), _footprint_tree).geometries
    flat = shapely.intersects(feet[ob[tall]], lines[seg[tall]])
    blocked[seg[tall][flat]] = True
    slab = ~tall
    hit = _slab_hits(
        centre[ob[slab]],
        c[ob[slab]],
        s[ob[slab]],
        lo[ob[slab]],
        hi[ob[slab]],
        a[seg[slab]],
        b[seg[slab]],
    )
    blocked[seg[slab][hit]] = True
    return blocked


def _boxes_of(floor_z: float) -> Any:
    """``make`` of :func:`_kept`: :func:`_box_arrays` on a floor at ``floor_z`` (m),
    read-only."""

    def make(obstacles: tuple[Obstacle, ...], margin: float, thread: int) -> tuple[NDArray, ...]:
        out = _box_arrays(floor_z, obstacles, margin)
        for x in out:
            x.flags.writeable = False
        return out

    return make


def _grown_tree(obstacles: tuple[Obstacle, ...], margin: float, thread: int) -> shapely.STRtree:
    """A search tree over the footprints grown by ``margin`` and :data:`NEAR_TOLERANCE` (a
    segment that meets a box crosses its grown footprint), for one ``thread``."""
    grown = margin + NEAR_TOLERANCE
    return shapely.STRtree([_footprint(ob, grown, ob.center) for ob in obstacles])


def _slab_hits(
    centre: NDArray,
    c: NDArray,
    s: NDArray,
    lo: NDArray,
    hi: NDArray,
    a: NDArray,
    b: NDArray,
) -> NDArray[np.bool_]:
    """Whether segments a-b cross boxes (the slab test), elementwise: boxes as
    :func:`_box_arrays` gives them with shapes (..., 2), (...), (...), (..., 3), (..., 3) and
    (N, 3) segment ends, broadcast to (...) over the boxes' leading axes (O, 1 against N
    segments gives (O, N); P gathered pairs give (P,))."""
    # Both ends in each obstacle's frame, per axis.
    qa, qb = [], []
    for p, q in ((a, qa), (b, qb)):
        dx, dy = p[:, 0] - centre[..., 0], p[:, 1] - centre[..., 1]
        q += [c * dx + s * dy, -s * dx + c * dy, np.broadcast_to(p[:, 2], dx.shape)]
    t0 = np.zeros(qa[0].shape)
    t1 = np.ones(qa[0].shape)
    # A segment (nearly) parallel to a slab gives infinite (or overflowing) slab
    # parameters: the comparisons below treat them as the limits they are.
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for k in range(3):
            d = qb[k] - qa[k]
            inv = 1.0 / d
            ta = (lo[..., k] - qa[k]) * inv
            tb = (hi[..., k] - qa[k]) * inv
            finite = np.isfinite(inv)
            tmin = np.where(finite, np.minimum(ta, tb), -np.inf)
            tmax = np.where(finite, np.maximum(ta, tb), np.inf)
            outside = ~finite & ((qa[k] < lo[..., k]) | (qa[k] > hi[..., k]))
            tmin = np.where(outside, np.inf, tmin)
            t0 = np.maximum(t0, tmin)
            t1 = np.minimum(t1, tmax)
    return t0 <= t1


def floor_view(
    camera: TsaiCamera, floor_z: float, max_range: float = 50.0, grid: int = 24
) -> NDArray[np.float64]:
    """Floor points seen by a camera, on a regular grid of its image.

    Args:
        camera: the camera (world frame).
        floor_z: height of the floor, m.
        max_range: rays that meet the floor farther than this (horizontal distance, m) are
            dropped, as are rays that do not meet it.
        grid: samples along each image axis.

    Returns:
        (N, 3) world points on the floor, m (N may be 0).
    """
    w, h = camera.image_size
    u, v = np.meshgrid(np.linspace(0, w - 1, grid), np.linspace(0, h - 1, grid))
    origins, dirs = camera.unproject(np.column_stack([u.ravel(), v.ravel()]))
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (floor_z - origins[:, 2]) / dirs[:, 2]
    ok = np.isfinite(t) & (t > 0)
    pts = origins[ok] + t[ok, None] * dirs[ok]
    horiz = np.linalg.norm(pts[:, :2] - camera.position[:2], axis=1)
    return pts[horiz <= max_range]


def floor_view_corners(
    camera: TsaiCamera, floor_z: float, max_range: float = 50.0
) -> NDArray[np.float64]:
    """Where the four image corners' rays meet the floor (a trapezoid), (K, 2), m.

    Corners whose rays miss the floor (above the horizon) are clipped to ``max_range``
    along the ray's horizontal direction. K = 4 unless the camera sees no floor (K = 0).
    """
    w, h = camera.image_size
    corners = np.array([[0, h - 1], [w - 1, h - 1], [w - 1, 0], [0, 0]], dtype=float)
    origins, dirs = camera.unproject(corners)
    out = []
    for o, d in zip(origins, dirs, strict=True):
        if d[2] < 0:
            t = (floor_z - o[2]) / d[2]
            p = o[:2] + t * d[:2]
            if np.linalg.norm(p - o[:2]) <= max_range:
                out.append(p)
                continue
        hd = d[:2] / max(np.linalg.norm(d[:2]), 1e-12)
        out.append(o[:2] + max_range * hd)
    pts = np.asarray(out)
    if not np.any(dirs[:, 2] < 0):
        return np.zeros((0, 2))
    return pts


def polyline_points(waypoints: ArrayLike, spacing: float) -> tuple[NDArray, NDArray]:
    """Points along a polyline, each segment cut into equal parts of at most ``spacing`` m
    (its ends included; a segment of no length adds none).

    Args:
        waypoints: (K, 2) points, m, K >= 2.
        spacing: m, > 0.

    Returns:
        points: (N, 2) points, m.
        segment: (N,) index of the segment each point lies on (from waypoint i to i + 1).
    """
    p = np.asarray(waypoints, dtype=float).reshape(-1, 2)
    if len(p) < 2:
        raise ValueError(f"a polyline needs at least 2 waypoints, got {len(p)}")
    moved = np.flatnonzero(np.any(p[1:] != p[:-1], axis=1))
    if not moved.size:  # every waypoint the same point
        return p[:1].copy(), np.zeros(1, dtype=np.intp)
    lines = shapely.linestrings(np.stack([p[moved], p[moved + 1]], axis=1))
    points, index = shapely.get_coordinates(shapely.segmentize(lines, spacing), return_index=True)
    return points, moved[index]
