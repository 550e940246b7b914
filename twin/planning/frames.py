"""The map's frame and the project's world frame W.

W is the parent's instrument frame at its first station (z up). A site planned on a map
keeps where that station stands in the map, :class:`MapPose`, so that points go either way
and results can be reported in the map's frame too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from shapely import affinity
from shapely.geometry.base import BaseGeometry


@dataclass(frozen=True)
class MapPose:
    """W's origin and heading in the map's frame.

    Attributes:
        x, y: the parent's first station in the map, m. yaw: W's x-axis from the map's x
            axis, counter-clockwise, rad.
    """

    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0

    def __post_init__(self) -> None:
        if not all(math.isfinite(v) for v in (self.x, self.y, self.yaw)):
            raise ValueError(f"a map pose must be finite, got {self}")

    def map2world(self, points: ArrayLike) -> NDArray[np.float64]:
        """(..., 2) map points -> (..., 2) W points, m."""
        p = np.asarray(points, dtype=float) - (self.x, self.y)
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return np.stack([c * p[..., 0] + s * p[..., 1], -s * p[..., 0] + c * p[..., 1]], axis=-1)

    def world2map(self, points: ArrayLike) -> NDArray[np.float64]:
        """(..., 2) W points -> (..., 2) map points, m."""
        p = np.asarray(points, dtype=float)
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        x = c * p[..., 0] - s * p[..., 1] + self.x
        y = s * p[..., 0] + c * p[..., 1] + self.y
        return np.stack([x, y], axis=-1)

    def direction2world(self, vectors: ArrayLike) -> NDArray[np.float64]:
        """(..., 2) directions in the map -> in W (turned only)."""
        v = np.asarray(vectors, dtype=float)
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return np.stack([c * v[..., 0] + s * v[..., 1], -s * v[..., 0] + c * v[..., 1]], axis=-1)

    def geometry2world(self, geometry: BaseGeometry) -> BaseGeometry:
        """A shapely geometry of the map, in W."""
        moved = affinity.translate(geometry, -self.x, -self.y)
        return affinity.rotate(moved, -self.yaw, origin=(0.0, 0.0), use_radians=True)
