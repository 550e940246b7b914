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

ROBOT_BODY = 0.45
"""A robot (with its mast) blocks a line of sight passing closer than this to its centre
(horizontal distance), m."""


def free(scenario: Scenario, points_xy: ArrayLike, clearance: float = ROBOT_CLEARANCE) -> NDArray:
    """(N,) whether a robot centred at each (N, 2) point keeps ``clearance`` from walls
    and obstacles."""
    p = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    ok = inside_space(scenario.space, p, clearance)
    for ob in scenario.space.obstacles:
        ok &= ~inside_obstacle(ob, p, clearance)
    return ok


def sight_clear(scenario: Scenario, starts: ArrayLike, ends: ArrayLike) -> NDArray[np.bool_]:
    """(N,) whether the map's obstacles leave each 3D segment free."""
    a = np.asarray(starts, dtype=float).reshape(-1, 3)
    b = np.asarray(ends, dtype=float).reshape(-1, 3)
    a, b = np.broadcast_arrays(a, b)
    return ~segment_blocked(scenario.space, a, b)


def passes_near(
    starts_xy: ArrayLike, ends_xy: ArrayLike, centre_xy: ArrayLike, distance: float = ROBOT_BODY
) -> NDArray[np.bool_]:
    """(N,) whether the horizontal segments pass within ``distance`` of a robot's centre
    (excluding a segment's own end, the target)."""
    a = np.asarray(starts_xy, dtype=float).reshape(-1, 2)
    b = np.asarray(ends_xy, dtype=float).reshape(-1, 2)
    a, b = np.broadcast_arrays(a, b)
    c = np.asarray(centre_xy, dtype=float).reshape(2)
    d = b - a
    n2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-12)
    t = np.clip(np.einsum("ij,ij->i", c - a, d) / n2, 0.0, 1.0)
    return np.linalg.norm(a + t[:, None] * d - c, axis=1) < distance


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


HIDDEN_CONE = np.radians(15.0)
"""A prism is taken as hidden by its own mast and arm when the viewer stands within this
angle of the direction from the prism through the mast (seen from above)."""


def prisms_hidden(
    xy: ArrayLike, yaw: float, cubes_body: ArrayLike, viewer_xy: ArrayLike
) -> NDArray[np.bool_]:
    """(3,) whether each prism of a child at ``xy``, ``yaw`` is behind its mast for a
    viewer at ``viewer_xy`` (the mast and the prism's arm hide it)."""
    cubes = body_points(xy, yaw, cubes_body, 0.0)[0][:, :2]
    mast = np.asarray(xy, dtype=float).reshape(2)
    view = np.asarray(viewer_xy, dtype=float).reshape(2) - mast
    arm = mast - cubes  # from each prism towards (and past) the mast
    cos = (arm @ view) / np.maximum(np.linalg.norm(arm, axis=1) * np.linalg.norm(view), 1e-12)
    return cos > np.cos(HIDDEN_CONE)


def unhidden_yaw(xy: ArrayLike, yaw: float, cubes_body: ArrayLike, viewers_xy: ArrayLike) -> float:
    """The heading nearest ``yaw`` (in 10 deg steps up to 60 deg) at which no prism is
    hidden from any viewer; ``yaw`` itself when none is."""
    viewers = np.asarray(viewers_xy, dtype=float).reshape(-1, 2)
    for step in (0, 10, -10, 20, -20, 30, -30, 40, -40, 50, -50, 60, -60):
        y = yaw + np.radians(step)
        if not any(prisms_hidden(xy, y, cubes_body, v).any() for v in viewers):
            return float(y)
    return float(yaw)
