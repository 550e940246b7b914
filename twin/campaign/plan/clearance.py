"""Clearance on the map: where a robot may stand and drive, which segments the map's
obstacles or a robot leave clear, and where a robot's body points stand.

The map (walls, obstacles) is what an installer knows before the robots start; the robots'
measurements never come from here."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.scenario.geometry import inside_obstacles, inside_space, polyline_points, segment_blocked
from twin.scenario.schema import Space

ROBOT_CLEARANCE = 0.45
"""Distance kept between a child's centre and walls or obstacles, m (its radius, 0.29 m,
and a margin for its stopping error)."""

CHILD_BODY = 0.32
"""Radius of a child's body with a margin, m."""

PARENT_BODY = 0.4
"""Radius of the parent's body with a margin, m."""

PARENT_TOP = 0.75
"""Height of the parent with its instrument above the floor, with a margin, m."""


def robot_fits(space: Space, points_xy: ArrayLike, clearance: float = ROBOT_CLEARANCE) -> NDArray:
    """(N,) whether a robot centred at each (N, 2) point keeps ``clearance`` (m) from the
    space's walls and obstacles."""
    p = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    blocked = inside_obstacles(space.obstacles, p, clearance).any(axis=0)
    return inside_space(space, p, clearance) & ~blocked


def path_clear(
    space: Space, start_xy: ArrayLike, end_xy: ArrayLike, clearance: float = ROBOT_CLEARANCE
) -> bool:
    """Whether a robot can drive straight from ``start_xy`` to ``end_xy`` keeping
    ``clearance`` from walls and obstacles (checked at most 0.1 m apart), m."""
    a = np.asarray(start_xy, dtype=float).reshape(2)
    b = np.asarray(end_xy, dtype=float).reshape(2)
    pts, _ = polyline_points([a, b], 0.1)
    return bool(robot_fits(space, pts, clearance).all())


def sight_clear(
    space: Space, starts: ArrayLike, ends: ArrayLike, margin: float = 0.0
) -> NDArray[np.bool_]:
    """(N,) whether the space's obstacles leave each 3D segment free (by ``margin``, m)."""
    a = np.asarray(starts, dtype=float).reshape(-1, 3)
    b = np.asarray(ends, dtype=float).reshape(-1, 3)
    a, b = np.broadcast_arrays(a, b)
    return ~segment_blocked(space, a, b, margin=margin)


def passes_near(
    starts: ArrayLike,
    ends: ArrayLike,
    centre_xy: ArrayLike,
    profile: tuple[tuple[float, float, float], ...],
) -> NDArray[np.bool_]:
    """(N,) whether 3D segments pass through a robot standing at ``centre_xy``.

    Args:
        starts, ends: (N, 3) segment ends, m (W).
        centre_xy: (2,) the robot's centre, m.
        profile: the robot as stacked cylinders ``(bottom_z, top_z, radius)``, m, heights
            in W (see :func:`child_profile`, :func:`parent_profile`).
    """
    a = np.asarray(starts, dtype=float).reshape(-1, 3)
    b = np.asarray(ends, dtype=float).reshape(-1, 3)
    a, b = np.broadcast_arrays(a, b)
    c = np.asarray(centre_xy, dtype=float).reshape(2)
    d = b[:, :2] - a[:, :2]
    n2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-12)
    t = np.clip(np.einsum("ij,ij->i", c - a[:, :2], d) / n2, 0.0, 1.0)
    dist = np.linalg.norm(a[:, :2] + t[:, None] * d - c, axis=1)
    z = a[:, 2] + t * (b[:, 2] - a[:, 2])
    hit = np.zeros(len(a), dtype=bool)
    for bottom, top, radius in profile:
        hit |= (dist < radius) & (z >= bottom) & (z <= top)
    return hit


def child_profile(floor_z: float, top: float = 1.45) -> tuple[tuple[float, float, float], ...]:
    """A child as cylinders (m): its body, the mast with the LEDs, the crown of prisms."""
    return (
        (floor_z - 1.0, floor_z + 0.35, CHILD_BODY),
        (floor_z + 0.35, floor_z + top - 0.1, 0.08),
        (floor_z + top - 0.1, floor_z + top, 0.25),
    )


def parent_profile(floor_z: float) -> tuple[tuple[float, float, float], ...]:
    """The parent with its instrument as one cylinder (m)."""
    return ((floor_z - 1.0, floor_z + PARENT_TOP, PARENT_BODY),)


def body_points(xy: ArrayLike, yaw: ArrayLike, points_body: ArrayLike, floor_z: float) -> NDArray:
    """(N, K, 3) world points of (K, 3) body points (origin on the floor) for N poses."""
    p = np.asarray(xy, dtype=float).reshape(-1, 2)
    y = np.asarray(yaw, dtype=float).reshape(-1)
    b = np.asarray(points_body, dtype=float).reshape(-1, 3)
    c, s = np.cos(y)[:, None], np.sin(y)[:, None]
    out = np.empty((*np.broadcast_shapes(p.shape[:1], y.shape), len(b), 3))
    out[..., 0] = p[:, None, 0] + c * b[None, :, 0] - s * b[None, :, 1]
    out[..., 1] = p[:, None, 1] + s * b[None, :, 0] + c * b[None, :, 1]
    out[..., 2] = floor_z + b[None, :, 2]
    return out


RANGE_MARGIN = 0.3
"""Prisms are planned at least this much beyond the instrument's minimum range, m."""


def in_range(distances: ArrayLike, instrument_range: tuple[float, float]) -> NDArray[np.bool_]:
    """Whether each distance (m) from the total station lies within its (least, greatest)
    range, the least with :data:`RANGE_MARGIN`."""
    d = np.asarray(distances, dtype=float)
    return (d >= instrument_range[0] + RANGE_MARGIN) & (d <= instrument_range[1])
