"""What the agent of :class:`twin.envs.CpsCampaignEnv` observes: a ``Dict`` of ``Box``
spaces, each entry described in :data:`ENTRIES`; everything comes from what the campaign
knows (its estimates and their covariances), nothing from the twin's truth."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from twin.envs.free_space import MAX_RANGE
from twin.scenario.schema import Space

DIRECTIONS = 8
"""Rays of ``free_space``."""

CAMERA_COLUMNS = (
    "present",
    "calibrated",
    "predicted_error",
    "transfer_now",
    "range",
    "cos_bearing",
    "sin_bearing",
    "here",
)
"""The columns of ``cameras``, one row per camera (padded rows are all zero)."""

STATION_COLUMNS = (
    "present",
    "camera",
    "calibrated",
    "route_distance",
    "range",
    "cos_bearing",
    "sin_bearing",
    "here",
)
"""The columns of ``stations``, one row per calibration station in the order of ``go_to``
(padded rows are all zero); ``camera`` is its camera's row in ``cameras`` plus one, over
``max_cameras``."""

ERROR_SCALE_M = 0.05
"""Scale of the camera errors observed (``predicted_error``, ``transfer_now``), m: 50 mm
reads 1 (the paper's hall's errors are 10-40 mm)."""

POSE_SCALE = 0.01
"""Scale of the parent's standard deviations observed: 10 mm (position) and 10 mrad (yaw)
read 1."""

TIME_SCALE_S = 3600.0
"""Scale of the campaign's time observed, s: an hour reads 1."""

ENTRIES = {
    "decision": "(2,) one-hot: a leg of a travel, or a decision between travels",
    "parent": "(4,) the parent's estimate: x, y (site units), cos yaw, sin yaw (W)",
    "parent_uncertainty": "(4, 4) of (yaw, x, y, z): on the diagonal the standard "
    "deviations (POSE_SCALE units: 10 mrad, 10 mm), off it the correlations",
    "child_robots": "(2, 4) each child's estimate: x, y (site units, CPS), cos and sin of its "
    "own yaw (W)",
    "travel": "(3,) distance travelled and budget left (budget units), campaign time (hours)",
    "goal": "(4,) travelling (0/1), range (site units), cos and sin of the bearing from the "
    "heading",
    "cameras": f"(max_cameras, {len(CAMERA_COLUMNS)}) per camera: {', '.join(CAMERA_COLUMNS)}",
    "stations": f"(max_stations, {len(STATION_COLUMNS)}) per station: {', '.join(STATION_COLUMNS)}",
    "free_space": "(8,) distance to the nearest wall or obstacle along rays from the heading "
    f"anticlockwise, in units of {MAX_RANGE:g} m (at most 1)",
}
"""Each entry of the observation, with its shape and units. Every value is float32 and
lies in the space's bounds (clipped to them). Positions are in site units: ``(x - centre) /
half`` with the centre and half the longest side of the site's floor
(:class:`SiteScale`), so that the site lies in [-1, 1]; ranges are in the same units (the
site's diagonal is at most 2 sqrt 2); route distances and travel in units of the travel
budget; errors in :data:`ERROR_SCALE_M`; time in :data:`TIME_SCALE_S`. No key is the name of
an attribute of torch's ``nn.Module`` (Stable-Baselines3's ``MultiInputPolicy`` makes one
module per key)."""

POSITION_BOUND = 2.0
"""Bound of a position in site units (an estimate may stray off the floor; clipped)."""

RANGE_BOUND = 4.0
"""Bound of a range in site units."""

ERROR_BOUND = 20.0
"""Bound of an error in :data:`ERROR_SCALE_M` units (1 m)."""

STD_BOUND = 100.0
"""Bound of a standard deviation in :data:`POSE_SCALE` units (1 m, 1 rad)."""

TRAVEL_BOUND = 4.0
"""Bound of a distance in budget units."""

TIME_BOUND = 24.0
"""Bound of the campaign's time, hours."""


@dataclass(frozen=True)
class SiteScale:
    """The site's units of the observation: positions ``(xy - centre) / half``.

    Attributes:
        centre: (2,) the middle of the site's floor, m (W). half: half its longest side, m.
    """

    centre: NDArray[np.float64]
    half: float

    @classmethod
    def of(cls, space: Space) -> SiteScale:
        """The units of a site's floor (its ``x_range`` and ``y_range``)."""
        (x0, x1), (y0, y1) = space.x_range, space.y_range
        half = max(x1 - x0, y1 - y0, 1e-3) / 2.0
        return cls(np.array([(x0 + x1) / 2.0, (y0 + y1) / 2.0]), float(half))


@lru_cache(maxsize=16)
def _bounds(max_cameras: int, max_stations: int) -> dict[str, tuple[NDArray, NDArray]]:
    """Each entry's (low, high), float32 (read-only)."""

    def box(shape: tuple[int, ...], low: float, high: float) -> tuple[NDArray, NDArray]:
        return np.full(shape, low, np.float32), np.full(shape, high, np.float32)

    def columns(lows: list[float], highs: list[float], rows: int) -> tuple[NDArray, NDArray]:
        return (
            np.tile(np.array(lows, np.float32), (rows, 1)),
            np.tile(np.array(highs, np.float32), (rows, 1)),
        )

    p, r = POSITION_BOUND, RANGE_BOUND
    std_low = np.full((4, 4), -1.0, np.float32)
    std_high = np.ones((4, 4), np.float32)
    np.fill_diagonal(std_low, 0.0)
    np.fill_diagonal(std_high, STD_BOUND)
    out = {
        "decision": box((2,), 0.0, 1.0),
        "parent": (np.array([-p, -p, -1, -1], np.float32), np.array([p, p, 1, 1], np.float32)),
        "parent_uncertainty": (std_low, std_high),
        "child_robots": columns([-p, -p, -1, -1], [p, p, 1, 1], 2),
        "travel": (
            np.array([0, -TRAVEL_BOUND, 0], np.float32),
            np.array([TRAVEL_BOUND, TRAVEL_BOUND, TIME_BOUND], np.float32),
        ),
        "goal": (np.array([0, 0, -1, -1], np.float32), np.array([1, r, 1, 1], np.float32)),
        "cameras": columns(
            [0, 0, 0, 0, 0, -1, -1, 0], [1, 1, ERROR_BOUND, ERROR_BOUND, r, 1, 1, 1], max_cameras
        ),
        "stations": columns(
            [0, 0, 0, 0, 0, -1, -1, 0], [1, 1, 1, TRAVEL_BOUND, r, 1, 1, 1], max_stations
        ),
        "free_space": box((DIRECTIONS,), 0.0, 1.0),
    }
    for low, high in out.values():
        low.flags.writeable = high.flags.writeable = False
    return out


def observation_space(max_cameras: int, max_stations: int) -> spaces.Dict:
    """The observation space for sites of up to ``max_cameras`` cameras and
    ``max_stations`` calibration stations (float32, the bounds of :data:`ENTRIES`)."""
    return spaces.Dict(
        {
            key: spaces.Box(low, high, dtype=np.float32)
            for key, (low, high) in _bounds(max_cameras, max_stations).items()
        }
    )


@dataclass(frozen=True)
class CameraState:
    """What the campaign knows of one camera.

    Attributes:
        calibrated: whether it has a calibration. predicted_error: the predicted RMS
            world-frame position error of its delivered calibration, m (0 when none).
        calibration_error: the part of it that comes from the calibration itself (not
            from the parent's pose), m (0 when none).
        transfer_now: the RMS position error the parent's pose would give it if it were
            calibrated from here, m. position: (3,) its nominal position, m (W).
        here: whether the parent stands at its station.
    """

    calibrated: bool
    predicted_error: float
    calibration_error: float
    transfer_now: float
    position: NDArray[np.float64]
    here: bool


@dataclass(frozen=True)
class Stations:
    """What the campaign knows of the site's calibration stations, in the order of
    ``go_to`` (S of them).

    Attributes:
        camera: (S,) each one's camera's index in the site (0 for the first).
        xy: (S, 2) m (W). route_distance: (S,) the parent's travel to each, m, or (R, S)
            one row a trial. here: the index of the station the parent stands at, or None;
            or (R,) one a trial, -1 for none.
    """

    camera: NDArray[np.int64]
    xy: NDArray[np.float64]
    route_distance: NDArray[np.float64]
    here: int | NDArray[np.int64] | None


def bearings(
    origin: NDArray[np.float64], heading: NDArray[np.float64], targets: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(R, N) range m, cos and sin of (N, 2+) ``targets`` seen from (R, 2) ``origin``
    facing (R,) ``heading`` rad (a target at the origin reads range 0, bearing 0)."""
    d = np.asarray(targets, dtype=float)[None, :, :2] - origin[:, None, :2]
    rng = np.hypot(d[..., 0], d[..., 1])
    angle = np.arctan2(d[..., 1], d[..., 0]) - heading[:, None]
    there = rng < 1e-9
    return (
        np.where(there, 0.0, rng),
        np.where(there, 1.0, np.cos(angle)),
        np.where(there, 0.0, np.sin(angle)),
    )


def _per_row(value: int | NDArray[np.int64] | None, n_rows: int) -> NDArray[np.int64]:
    """(R,) an index for every row (-1: none) from one for all (None: none) or (R,)."""
    if value is None:
        return np.full(n_rows, -1, dtype=np.int64)
    return np.broadcast_to(np.asarray(value, dtype=np.int64), (n_rows,))


def _mark(table: NDArray[np.float64], index: NDArray[np.int64], column: int) -> None:
    """Set ``table[r, index[r], column] = 1`` where ``index[r] >= 0``."""
    rows = np.flatnonzero(index >= 0)
    table[rows, index[rows], column] = 1.0


def _decisions(decision: str | Sequence[str | None] | None, n_rows: int) -> NDArray[np.float64]:
    """(R, 2) whether each trial is at a leg, between travels."""
    each = [decision] * n_rows if decision is None or isinstance(decision, str) else decision
    return np.array([[d == "leg", d == "visit"] for d in each], dtype=float).reshape(n_rows, 2)


def build_observations(
    *,
    decision: str | Sequence[str | None] | None,
    parent_xy: NDArray[np.float64],
    parent_yaw: NDArray[np.float64],
    parent_covariance: NDArray[np.float64],
    children_pose: NDArray[np.float64],
    travel: NDArray[np.float64],
    goal_xy: NDArray[np.float64] | None,
    camera_xyz: NDArray[np.float64],
    calibrated: NDArray[np.bool_],
    predicted_error: NDArray[np.float64],
    transfer_now: NDArray[np.float64],
    here_camera: int | NDArray[np.int64] | None,
    max_cameras: int,
    stations: Stations,
    max_stations: int,
    free_space: NDArray[np.float64],
    site: SiteScale,
    budget_m: float,
) -> dict[str, NDArray[np.float32]]:
    """The observations (see :data:`ENTRIES`) of R trials of one site, each entry with a
    leading axis of R, float32, every value finite and within the space's bounds. What the
    campaigns' planners say (``decision``, ``goal_xy``, ``here_camera``, the stations' route
    distances and ``here``) is one for every trial, or one a trial.

    Args:
        parent_xy: (R, 2) m. parent_yaw: (R,) rad. parent_covariance: (R, 4, 4) of
            (yaw rad, x m, y m, z m). children_pose: (R, N_child, 3) x m, y m, yaw rad.
        travel: (R, 3) distance travelled m, budget left m, campaign time s.
        decision: ``leg``, ``visit`` or None, or one of them a trial.
        goal_xy: (2,) the station travelled to (at a leg), m, or None; or (R, 2) one a
            trial, NaN for none.
        camera_xyz: (C, 3) the cameras' nominal positions, m. calibrated,
            predicted_error, transfer_now: (R, C) (see
            :class:`twin.envs.knowledge.Knowledge`), m. here_camera: the index of the
            camera whose station the parent stands at, or None; or (R,) one a trial, -1
            for none.
        stations: the calibration stations. free_space: (R, DIRECTIONS) m.
        site: the site's units of position. budget_m: the travel budget, m (the unit of
            distances along the route).
    """
    n_rows, n_cams = calibrated.shape
    unit = 1.0 / site.half
    cameras = np.zeros((n_rows, max_cameras, len(CAMERA_COLUMNS)))
    if n_cams:
        rng, c, s = bearings(parent_xy, parent_yaw, camera_xyz)
        cameras[:, :n_cams, 0] = 1.0
        cameras[:, :n_cams, 1] = calibrated
        cameras[:, :n_cams, 2] = predicted_error / ERROR_SCALE_M
        cameras[:, :n_cams, 3] = transfer_now / ERROR_SCALE_M
        cameras[:, :n_cams, 4:7] = np.stack([rng * unit, c, s], axis=-1)
        _mark(cameras, _per_row(here_camera, n_rows), 7)
    table = np.zeros((n_rows, max_stations, len(STATION_COLUMNS)))
    n_st = len(stations.camera)
    if n_st:
        rng, c, s = bearings(parent_xy, parent_yaw, stations.xy)
        table[:, :n_st, 0] = 1.0
        table[:, :n_st, 1] = (stations.camera + 1) / max_cameras
        table[:, :n_st, 2] = calibrated[:, stations.camera]
        table[:, :n_st, 3] = stations.route_distance / budget_m
        table[:, :n_st, 4:7] = np.stack([rng * unit, c, s], axis=-1)
        _mark(table, _per_row(stations.here, n_rows), 7)
    goal = np.zeros((n_rows, 4))
    if goal_xy is not None:
        target = np.broadcast_to(np.asarray(goal_xy, dtype=float), (n_rows, 2))
        going = np.flatnonzero(np.isfinite(target).all(axis=1))
        d = target[going] - parent_xy[going, :2]
        rng = np.hypot(d[:, 0], d[:, 1])
        angle = np.arctan2(d[:, 1], d[:, 0]) - parent_yaw[going]
        there = rng < 1e-9
        goal[going, 0] = 1.0
        goal[going, 1] = np.where(there, 0.0, rng) * unit
        goal[going, 2] = np.where(there, 1.0, np.cos(angle))
        goal[going, 3] = np.where(there, 0.0, np.sin(angle))
    children = np.zeros((n_rows, 2, 4))
    shown = min(2, children_pose.shape[1])
    children[:, :shown, :2] = (children_pose[:, :shown, :2] - site.centre) * unit
    children[:, :shown, 2] = np.cos(children_pose[:, :shown, 2])
    children[:, :shown, 3] = np.sin(children_pose[:, :shown, 2])
    std = np.sqrt(np.maximum(np.diagonal(parent_covariance, axis1=1, axis2=2), 0.0))
    outer = std[:, :, None] * std[:, None, :]
    uncertainty = np.divide(
        parent_covariance, outer, out=np.zeros_like(parent_covariance), where=outer > 0
    )
    index = np.arange(4)
    uncertainty[:, index, index] = std / POSE_SCALE
    travel = np.asarray(travel, dtype=float)
    obs = {
        "decision": _decisions(decision, n_rows),
        "parent": np.column_stack(
            [(parent_xy[:, :2] - site.centre) * unit, np.cos(parent_yaw), np.sin(parent_yaw)]
        ),
        "parent_uncertainty": uncertainty,
        "child_robots": children,
        "travel": np.column_stack(
            [travel[:, 0] / budget_m, travel[:, 1] / budget_m, travel[:, 2] / TIME_SCALE_S]
        ),
        "goal": goal,
        "cameras": cameras,
        "stations": table,
        "free_space": np.asarray(free_space, dtype=float) / MAX_RANGE,
    }
    bounds = _bounds(max_cameras, max_stations)
    return {
        k: np.clip(np.nan_to_num(v, nan=0.0), *bounds[k]).astype(np.float32) for k, v in obs.items()
    }
