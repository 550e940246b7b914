"""How much of a camera's view the total station sees from a station: what the scenario's
validation demands of a calibration station, and what a strategy asks when it chooses the
cameras whose reference data sets the first station can take."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from calib.camera import TsaiCamera
from twin.scenario.geometry import (
    floor_view,
    inside_obstacles,
    inside_space,
    obstacles_near,
    segment_blocked,
)
from twin.scenario.robots import PIONEER3DX
from twin.scenario.schema import Space

CHILD_CLEARANCE = PIONEER3DX.radius
"""Clearance kept between a child's centre and walls or obstacles, m: its footprint's
enclosing radius."""


def station_visibility(
    space: Space,
    camera: TsaiCamera,
    station_xy: ArrayLike,
    instrument_z: float,
    prism_height: float,
    instrument_range: tuple[float, float],
) -> float:
    """Fraction of a camera's reachable floor view whose prisms the total station sees from
    a station (line of sight clear of obstacles, slope distance in range).

    The view is sampled on a grid over the image; samples in obstacles or closer than a
    child's radius to a wall are not counted.

    Args:
        space: the map. camera: the camera's nominal model (W).
        station_xy: (2,) the parent's station, m. instrument_z: the instrument's height, m.
        prism_height: the prisms' height above the floor, m.
        instrument_range: the total station's (least, greatest) distance, m.

    Returns:
        The fraction, 0 when the camera sees no such floor.
    """
    floor = floor_view(camera, space.floor_z, max_range=60.0)
    if len(floor) == 0:
        return 0.0
    station = np.asarray(station_xy, dtype=float).reshape(2)
    # Only obstacles near the view and the station can hide the one from the other.
    near = obstacles_near(space.obstacles, np.vstack([floor[:, :2], station]), CHILD_CLEARANCE)
    ok = inside_space(space, floor[:, :2], CHILD_CLEARANCE)
    ok &= ~inside_obstacles(near, floor[:, :2], CHILD_CLEARANCE).any(axis=0)
    floor = floor[ok]
    if len(floor) == 0:
        return 0.0
    targets = floor + np.array([0.0, 0.0, prism_height])
    inst = np.array([station[0], station[1], instrument_z])
    dist = np.linalg.norm(targets - inst, axis=1)
    in_range = (dist >= instrument_range[0]) & (dist <= instrument_range[1])
    if not near:
        return float(np.mean(in_range))
    clear = ~segment_blocked(space, np.broadcast_to(inst, targets.shape), targets, near)
    return float(np.mean(in_range & clear))
