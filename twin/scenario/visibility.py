"""How much of a camera's view the total station sees from a station: what the scenario's
validation demands of a calibration station, and what a strategy asks when it chooses the
cameras whose reference data sets the first station can take."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

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

    The view is sampled on a grid over the image; samples in obstacles, closer than a
    child's radius to a wall, or hidden from the camera itself by an obstacle (a child
    there would show no LED) are not counted.

    Args:
        space: the map. camera: the camera's nominal model (W).
        station_xy: (2,) the parent's station, m. instrument_z: the instrument's height, m.
        prism_height: the prisms' height above the floor, m.
        instrument_range: the total station's (least, greatest) distance, m.

    Returns:
        The fraction, 0 when the camera sees no such floor.
    """
    station = np.asarray(station_xy, dtype=float).reshape(1, 2)
    fraction = stations_visibility(
        space, camera, station, instrument_z, prism_height, instrument_range
    )
    return float(fraction[0])


SEGMENTS_AT_ONCE = 100_000
"""Lines of sight :func:`stations_visibility` tests in one call (bounds its memory)."""


def stations_visibility(
    space: Space,
    camera: TsaiCamera,
    stations_xy: ArrayLike,
    instrument_z: float,
    prism_height: float,
    instrument_range: tuple[float, float],
) -> NDArray[np.float64]:
    """:func:`station_visibility` from each of (K, 2) stations (m): (K,) fractions. The
    camera's floor view is cast once, and the lines of sight of many stations are tested
    in one call."""
    stations = np.asarray(stations_xy, dtype=float).reshape(-1, 2)
    out = np.zeros(len(stations))
    floor = floor_view(camera, space.floor_z, max_range=60.0)
    if len(floor) == 0 or len(stations) == 0:
        return out
    # Only obstacles near the view can hold a sample of it.
    near = obstacles_near(space.obstacles, floor[:, :2], CHILD_CLEARANCE)
    ok = inside_space(space, floor[:, :2], CHILD_CLEARANCE)
    ok &= ~inside_obstacles(near, floor[:, :2], CHILD_CLEARANCE).any(axis=0)
    targets = floor[ok] + np.array([0.0, 0.0, prism_height])
    # Only the floor the camera itself sees: a wall just before a camera hides the view's
    # far floor from it, whoever stands there.
    if len(targets) and space.obstacles:
        targets = targets[~segment_blocked(space, camera.position, targets)]
    if len(targets) == 0:
        return out
    inst = np.column_stack([stations, np.full(len(stations), instrument_z)])
    dist = np.linalg.norm(targets[None] - inst[:, None], axis=2)  # (K, M)
    seen = (dist >= instrument_range[0]) & (dist <= instrument_range[1])
    if space.obstacles:
        step = max(1, SEGMENTS_AT_ONCE // len(targets))
        for lo in range(0, len(stations), step):
            rows, cols = np.nonzero(seen[lo : lo + step])
            if rows.size:
                blocked = segment_blocked(space, inst[lo + rows], targets[cols])
                seen[lo + rows[blocked], cols[blocked]] = False
    return np.mean(seen, axis=1)
