"""Plan geometry of a scenario, pure numpy: obstacles as boxes, camera views on the floor,
segment tests. Used to validate scenarios and to summarise them, without MuJoCo.

Obstacles are treated as their bounding boxes (stairs included), which is conservative
for lines of sight.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.camera import TsaiCamera
from twin.scenario.schema import Obstacle, Space


def world2box(obstacle: Obstacle, points: ArrayLike) -> NDArray[np.float64]:
    """(N, 2) or (N, 3) world points -> the same points in the obstacle's frame (centre of
    the footprint, axes along its sides; z unchanged)."""
    p = np.array(points, dtype=float, ndmin=2)
    c, s = np.cos(obstacle.yaw), np.sin(obstacle.yaw)
    dx = p[:, 0] - obstacle.center[0]
    dy = p[:, 1] - obstacle.center[1]
    out = p.copy()
    out[:, 0] = c * dx + s * dy
    out[:, 1] = -s * dx + c * dy
    return out


def inside_obstacle(
    obstacle: Obstacle, points_xy: ArrayLike, margin: float = 0.0
) -> NDArray[np.bool_]:
    """(N,) True where (N, 2) floor points lie in the footprint grown by ``margin`` (m)."""
    q = world2box(obstacle, points_xy)
    hx, hy = 0.5 * obstacle.size[0] + margin, 0.5 * obstacle.size[1] + margin
    return (np.abs(q[:, 0]) <= hx) & (np.abs(q[:, 1]) <= hy)


def obstacles_near(
    obstacles: tuple[Obstacle, ...], points_xy: ArrayLike, margin: float = 0.0
) -> tuple[Obstacle, ...]:
    """The obstacles whose footprint grown by ``margin`` (m) may reach the bounding box of
    (N, 2) floor points: the only ones that can hold one of the points within ``margin`` or
    block a segment between two of them. A cheap test (each footprint as its enclosing
    circle) that spares the exact ones most obstacles of a large space."""
    if not obstacles:
        return ()
    p = np.array(points_xy, dtype=float, ndmin=2)
    centre = np.array([ob.center for ob in obstacles], dtype=float)
    radius = np.array([0.5 * np.hypot(ob.size[0], ob.size[1]) for ob in obstacles]) + margin
    nearest = np.clip(centre, p.min(axis=0), p.max(axis=0))
    near = np.hypot(*(centre - nearest).T) <= radius
    return tuple(ob for ob, ok in zip(obstacles, near, strict=True) if ok)


def rectangle_corners(center: ArrayLike, size: ArrayLike, yaw: float = 0.0) -> NDArray[np.float64]:
    """(4, 2) corners of a rectangle of (length, width) ``size`` (m) turned by ``yaw`` (rad)
    about its ``center``."""
    hx, hy = 0.5 * float(size[0]), 0.5 * float(size[1])
    local = np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]])
    c, s = np.cos(yaw), np.sin(yaw)
    return local @ np.array([[c, s], [-s, c]]) + np.asarray(center, dtype=float)


def inside_space(space: Space, points_xy: ArrayLike, margin: float = 0.0) -> NDArray[np.bool_]:
    """(N,) True where (N, 2) points lie inside the walls, at least ``margin`` (m) from them."""
    p = np.array(points_xy, dtype=float, ndmin=2)
    (x0, x1), (y0, y1) = space.x_range, space.y_range
    return (
        (p[:, 0] >= x0 + margin)
        & (p[:, 0] <= x1 - margin)
        & (p[:, 1] >= y0 + margin)
        & (p[:, 1] <= y1 - margin)
    )


def _boxes(
    space: Space, obstacles: tuple[Obstacle, ...], margin: float = 0.0
) -> tuple[NDArray, ...]:
    """The obstacles' boxes as arrays: (O, 2) centres, (O,) cos and sin of their yaws, and
    (O, 3) lowest and highest corners in their own frames (see :func:`world2box`), m; the
    sides and the top moved out by ``margin``, m."""
    obs = obstacles or space.obstacles
    centre = np.array([ob.center for ob in obs], dtype=float).reshape(-1, 2)
    yaw = [ob.yaw for ob in obs]
    c = np.array([np.cos(y) for y in yaw])
    s = np.array([np.sin(y) for y in yaw])
    size = np.array([ob.size for ob in obs], dtype=float).reshape(-1, 3)
    half = 0.5 * size[:, :2] + margin
    lo = np.column_stack([-half, np.full(len(obs), space.floor_z)])
    hi = np.column_stack([half, space.floor_z + size[:, 2] + margin])
    return centre, c, s, lo, hi


def segment_blocked(
    space: Space,
    starts: ArrayLike,
    ends: ArrayLike,
    obstacles: tuple[Obstacle, ...] = (),
    margin: float = 0.0,
) -> NDArray[np.bool_]:
    """(N,) True where the 3D segment from starts[i] to ends[i] crosses an obstacle's box.

    The slab test, for all segments and obstacles at once.

    Args:
        space: gives the floor height (obstacles stand on the floor).
        starts, ends: (N, 3) world points, m.
        obstacles: the boxes to test (default: all of the space's obstacles).
        margin: pass at least this far from every box's sides and top, m.
    """
    a = np.array(starts, dtype=float, ndmin=2)
    b = np.array(ends, dtype=float, ndmin=2)
    a, b = np.broadcast_arrays(a, b)
    centre, c, s, lo, hi = (x[:, None] for x in _boxes(space, obstacles, margin))
    # Both ends in each obstacle's frame, (O, N) per axis (as world2box).
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
    return (t0 <= t1).any(axis=0)


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
    """Points every ``spacing`` m along a polyline.

    Returns:
        points: (N, 2) points, m.
        segment: (N,) index of the segment each point lies on.
    """
    p = np.asarray(waypoints, dtype=float)
    pts, seg = [], []
    for i in range(len(p) - 1):
        n = max(2, int(np.ceil(np.linalg.norm(p[i + 1] - p[i]) / spacing)) + 1)
        t = np.linspace(0.0, 1.0, n)[:, None]
        pts.append(p[i] + t * (p[i + 1] - p[i]))
        seg.append(np.full(n, i))
    return np.vstack(pts), np.concatenate(seg)
