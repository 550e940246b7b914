"""Planning geometry on the scenario's map: where a robot may stand, what the total station
and a camera can see. The map (walls, obstacles, nominal camera poses) is what an installer
knows before the robots start; the robots' measurements never come from here."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.scenario.geometry import inside_obstacle, inside_space, segment_blocked
from twin.scenario.schema import Scenario

ROBOT_CLEARANCE = 0.45
"""Distance kept between a child's centre and walls or obstacles, m (its radius, 0.29 m,
and a margin for its stopping error)."""

CHILD_BODY = 0.32
"""Radius of a child's body with a margin, m."""

PARENT_BODY = 0.4
"""Radius of the parent's body with a margin, m."""

PARENT_TOP = 0.75
"""Height of the parent with its instrument above the floor, with a margin, m."""


def free(scenario: Scenario, points_xy: ArrayLike, clearance: float = ROBOT_CLEARANCE) -> NDArray:
    """(N,) whether a robot centred at each (N, 2) point keeps ``clearance`` from walls
    and obstacles."""
    p = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    ok = inside_space(scenario.space, p, clearance)
    for ob in scenario.space.obstacles:
        ok &= ~inside_obstacle(ob, p, clearance)
    return ok


def path_clear(
    scenario: Scenario, start_xy: ArrayLike, end_xy: ArrayLike, clearance: float = ROBOT_CLEARANCE
) -> bool:
    """Whether a robot can drive straight from ``start_xy`` to ``end_xy`` keeping
    ``clearance`` from walls and obstacles (checked every 0.1 m), m."""
    a = np.asarray(start_xy, dtype=float).reshape(2)
    b = np.asarray(end_xy, dtype=float).reshape(2)
    n = max(2, int(np.ceil(np.linalg.norm(b - a) / 0.1)) + 1)
    pts = a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)
    return bool(free(scenario, pts, clearance).all())


def sight_clear(scenario: Scenario, starts: ArrayLike, ends: ArrayLike) -> NDArray[np.bool_]:
    """(N,) whether the map's obstacles leave each 3D segment free."""
    a = np.asarray(starts, dtype=float).reshape(-1, 3)
    b = np.asarray(ends, dtype=float).reshape(-1, 3)
    a, b = np.broadcast_arrays(a, b)
    return ~segment_blocked(scenario.space, a, b)


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
    x = p[:, None, 0] + c * b[None, :, 0] - s * b[None, :, 1]
    yy = p[:, None, 1] + s * b[None, :, 0] + c * b[None, :, 1]
    z = np.broadcast_to(floor_z + b[None, :, 2], x.shape)
    return np.stack([x, yy, z], axis=-1)


MAST_RADIUS = 0.02
"""The mast's radius with a margin, m (the assembly's mast stands on the body axis up to
the prisms' height)."""

ARM_RADIUS = 0.015
"""An arm's radius with a margin, m (arms run from the mast to each prism, just below it)."""

PRISM_RADIUS = 0.04
"""A prism housing's radius with a margin, m."""

OWN_HOUSING = 0.045
"""The last part of a line of sight, m, that ends in the prism's own housing."""


def _segment_distance(points: NDArray, a: NDArray, b: NDArray) -> NDArray:
    """(N,) distances of (N, 3) points to the segment a-b."""
    d = b - a
    t = np.clip((points - a) @ d / max(float(d @ d), 1e-12), 0.0, 1.0)
    return np.linalg.norm(points - (a + t[:, None] * d), axis=1)


def prisms_hidden(
    xy: ArrayLike,
    yaw: float,
    cubes_body: ArrayLike,
    viewer: ArrayLike,
    floor_z: float,
) -> NDArray[np.bool_]:
    """(3,) whether each prism of a child at ``xy``, ``yaw`` is hidden from the instrument
    at ``viewer`` ((3,) m, W) by the assembly itself: its mast, the arms that hold the
    prisms, or another prism (they all stand at about one height, so at a grazing view one
    can stand in front of another)."""
    cubes = body_points(xy, yaw, cubes_body, floor_z)[0]
    base = np.array([*np.asarray(xy, dtype=float).reshape(2), floor_z])
    top = float(cubes[:, 2].max())
    mast = (base, np.array([base[0], base[1], top]))
    eye = np.asarray(viewer, dtype=float).reshape(3)
    hidden = np.zeros(len(cubes), dtype=bool)
    for k, target in enumerate(cubes):
        v = target - eye
        n = float(np.linalg.norm(v))
        # Sample the last 0.6 m of the line of sight (the assembly is 0.2 m across).
        t = np.arange(max(n - 0.6, 0.0), n - OWN_HOUSING, 0.002)
        ray = eye + np.outer(t / n, v)
        if _segment_distance(ray, *mast).min() < MAST_RADIUS:
            hidden[k] = True
            continue
        for j, other in enumerate(cubes):
            # Every arm counts, the prism's own too (seen from below, the line of sight can
            # graze it just before the housing); other prisms' housings count.
            arm_end = np.array([other[0], other[1], other[2] - 0.02])
            arm_start = np.array([base[0], base[1], other[2] - 0.02])
            near_arm = _segment_distance(ray, arm_start, arm_end).min() < ARM_RADIUS
            near_prism = j != k and np.linalg.norm(ray - other, axis=1).min() < PRISM_RADIUS
            if near_arm or near_prism:
                hidden[k] = True
                break
    return hidden


def unhidden_yaw(
    xy: ArrayLike,
    yaw: float,
    cubes_body: ArrayLike,
    viewers: ArrayLike,
    floor_z: float,
    max_turn_deg: float = 90.0,
) -> float | None:
    """The heading nearest ``yaw`` (in 10 deg steps up to ``max_turn_deg``) at which no
    prism is hidden from any viewer ((K, 3) instrument positions, m); None if none is."""
    eyes = np.asarray(viewers, dtype=float).reshape(-1, 3)
    turns = np.arange(10.0, max_turn_deg + 1e-9, 10.0)
    for step in [0.0, *np.ravel(np.column_stack([turns, -turns]))]:
        y = yaw + np.radians(step)
        if not any(prisms_hidden(xy, y, cubes_body, e, floor_z).any() for e in eyes):
            return float(y)
    return None
