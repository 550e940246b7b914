"""The free space around the robot group, from a raster of the site's floor plan."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from twin.scenario.schema import Space

RESOLUTION = 0.1
"""Side of a raster cell, m."""

MAX_RANGE = 20.0
"""Farthest distance a ray is followed, m (a ray that meets nothing reads this)."""


class FreeSpace:
    """Which cells of the floor are blocked (outside the walls, or under an obstacle).

    Args:
        space: the site. resolution: the cells' side, m.
    """

    def __init__(self, space: Space, resolution: float = RESOLUTION) -> None:
        (x0, x1), (y0, y1) = space.x_range, space.y_range
        self.origin = np.array([x0, y0])
        self.resolution = resolution
        nx = math.ceil((x1 - x0) / resolution)
        ny = math.ceil((y1 - y0) / resolution)
        xs = x0 + (np.arange(nx) + 0.5) * resolution
        ys = y0 + (np.arange(ny) + 0.5) * resolution
        gx, gy = np.meshgrid(xs, ys, indexing="ij")
        blocked = np.zeros((nx, ny), dtype=bool)
        for obstacle in space.obstacles:
            c, s = math.cos(obstacle.yaw), math.sin(obstacle.yaw)
            dx, dy = gx - obstacle.center[0], gy - obstacle.center[1]
            u, v = c * dx + s * dy, -s * dx + c * dy
            blocked |= (np.abs(u) <= obstacle.size[0] / 2) & (np.abs(v) <= obstacle.size[1] / 2)
        self.blocked = blocked

    def rays(
        self, xy: NDArray[np.float64], heading: NDArray[np.float64], directions: int = 8
    ) -> NDArray[np.float64]:
        """(R, directions) distance from each of (R, 2) ``xy`` (m) to the first blocked cell
        along ``directions`` rays evenly spread from its (R,) ``heading`` (rad)
        anticlockwise, m, at most :data:`MAX_RANGE`."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        heading = np.asarray(heading, dtype=float).reshape(-1)
        steps = np.arange(1, int(MAX_RANGE / self.resolution) + 1) * self.resolution
        angles = heading[:, None] + 2 * math.pi * np.arange(directions) / directions
        px = xy[:, 0, None, None] + np.cos(angles)[..., None] * steps
        py = xy[:, 1, None, None] + np.sin(angles)[..., None] * steps
        ix = np.floor((px - self.origin[0]) / self.resolution).astype(int)
        iy = np.floor((py - self.origin[1]) / self.resolution).astype(int)
        nx, ny = self.blocked.shape
        outside = (ix < 0) | (iy < 0) | (ix >= nx) | (iy >= ny)
        hit = outside.copy()
        inside = ~outside
        hit[inside] = self.blocked[ix[inside], iy[inside]]
        first = np.where(hit.any(axis=-1), hit.argmax(axis=-1), len(steps))
        return np.concatenate([[0.0], steps])[first]
