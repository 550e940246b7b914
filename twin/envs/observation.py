"""What the agent of :class:`twin.envs.CpsCampaignEnv` observes: a ``Dict`` of ``Box``
spaces, each entry described in :data:`ENTRIES`; everything comes from what the campaign
knows (its estimates and their covariances), nothing from the twin's truth."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from twin.envs.free_space import MAX_RANGE

DIRECTIONS = 8
"""Rays of ``free_space``."""

CAMERA_COLUMNS = (
    "present",
    "calibrated",
    "predicted_error_m",
    "transfer_now_m",
    "range_m",
    "cos_bearing",
    "sin_bearing",
    "here",
)
"""The columns of ``cameras``, one row per camera (padded rows are all zero)."""

STATION_COLUMNS = (
    "present",
    "camera",
    "calibrated",
    "route_distance_m",
    "range_m",
    "cos_bearing",
    "sin_bearing",
    "here",
)
"""The columns of ``stations``, one row per calibration station in the order of ``go_to``
(padded rows are all zero); ``camera`` is its camera's row in ``cameras`` plus one."""

ENTRIES = {
    "decision": "(2,) one-hot: a leg of a travel, or a decision between travels",
    "parent": "(4,) the parent's estimate: x m, y m, cos yaw, sin yaw (W)",
    "parent_covariance": "(4, 4) its covariance of (yaw mrad, x mm, y mm, z mm)",
    "children": "(2, 4) each child's estimate: x m, y m (CPS), cos and sin of its own yaw (W)",
    "travel": "(3,) distance travelled m, budget left m, campaign time s",
    "goal": "(4,) travelling (0/1), range m, cos and sin of the bearing from the heading",
    "cameras": f"(max_cameras, {len(CAMERA_COLUMNS)}) per camera: {', '.join(CAMERA_COLUMNS)}",
    "stations": f"(max_stations, {len(STATION_COLUMNS)}) per station: {', '.join(STATION_COLUMNS)}",
    "free_space": f"({DIRECTIONS},) distance to the nearest wall or obstacle along rays from "
    f"the heading anticlockwise, m (at most {MAX_RANGE:g})",
}
"""Each entry of the observation, with its shape and units."""


LARGE = 1e6
"""Bound of the entries with no natural one (positions m, covariances mm^2, seconds): the
observation is clipped to it, so that it always lies in the space."""


def observation_space(max_cameras: int, max_stations: int) -> spaces.Dict:
    """The observation space for sites of up to ``max_cameras`` cameras and
    ``max_stations`` calibration stations."""

    def box(shape: tuple[int, ...], low: float = -LARGE, high: float = LARGE) -> spaces.Box:
        return spaces.Box(low, high, shape, dtype=np.float64)

    camera_low = np.zeros((max_cameras, len(CAMERA_COLUMNS)))
    camera_high = np.full((max_cameras, len(CAMERA_COLUMNS)), LARGE)
    camera_low[:, [5, 6]] = -1.0  # cos, sin
    camera_high[:, [0, 1, 5, 6, 7]] = 1.0
    station_low = np.zeros((max_stations, len(STATION_COLUMNS)))
    station_high = np.full((max_stations, len(STATION_COLUMNS)), LARGE)
    station_low[:, [5, 6]] = -1.0
    station_high[:, [0, 2, 5, 6, 7]] = 1.0
    return spaces.Dict(
        {
            "decision": box((2,), 0.0, 1.0),
            "parent": box((4,)),
            "parent_covariance": box((4, 4)),
            "children": box((2, 4)),
            "travel": box((3,)),
            "goal": box((4,)),
            "cameras": spaces.Box(camera_low, camera_high, dtype=np.float64),
            "stations": spaces.Box(station_low, station_high, dtype=np.float64),
            "free_space": box((DIRECTIONS,), 0.0, MAX_RANGE),
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
) -> dict[str, NDArray[np.float64]]:
    """The observations (see :data:`ENTRIES`) of R trials of one site, each entry with a
    leading axis of R, every value finite. What the campaigns' planners say (``decision``,
    ``goal_xy``, ``here_camera``, the stations' route distances and ``here``) is one for
    every trial, or one a trial.

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
    """
    n_rows, n_cams = calibrated.shape
    scale = np.array([1e3, 1e3, 1e3, 1e3])  # rad -> mrad, m -> mm
    cameras = np.zeros((n_rows, max_cameras, len(CAMERA_COLUMNS)))
    if n_cams:
        rng, c, s = bearings(parent_xy, parent_yaw, camera_xyz)
        cameras[:, :n_cams, 0] = 1.0
        cameras[:, :n_cams, 1] = calibrated
        cameras[:, :n_cams, 2] = predicted_error
        cameras[:, :n_cams, 3] = transfer_now
        cameras[:, :n_cams, 4:7] = np.stack([rng, c, s], axis=-1)
        _mark(cameras, _per_row(here_camera, n_rows), 7)
    table = np.zeros((n_rows, max_stations, len(STATION_COLUMNS)))
    n_st = len(stations.camera)
    if n_st:
        rng, c, s = bearings(parent_xy, parent_yaw, stations.xy)
        table[:, :n_st, 0] = 1.0
        table[:, :n_st, 1] = stations.camera + 1
        table[:, :n_st, 2] = calibrated[:, stations.camera]
        table[:, :n_st, 3] = stations.route_distance
        table[:, :n_st, 4:7] = np.stack([rng, c, s], axis=-1)
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
        goal[going, 1] = np.where(there, 0.0, rng)
        goal[going, 2] = np.where(there, 1.0, np.cos(angle))
        goal[going, 3] = np.where(there, 0.0, np.sin(angle))
    children = np.zeros((n_rows, 2, 4))
    shown = min(2, children_pose.shape[1])
    children[:, :shown, :2] = children_pose[:, :shown, :2]
    children[:, :shown, 2] = np.cos(children_pose[:, :shown, 2])
    children[:, :shown, 3] = np.sin(children_pose[:, :shown, 2])
    obs = {
        "decision": _decisions(decision, n_rows),
        "parent": np.column_stack(
            [parent_xy[:, 0], parent_xy[:, 1], np.cos(parent_yaw), np.sin(parent_yaw)]
        ),
        "parent_covariance": parent_covariance * np.outer(scale, scale),
        "children": children,
        "travel": np.asarray(travel, dtype=float),
        "goal": goal,
        "cameras": cameras,
        "stations": table,
        "free_space": np.asarray(free_space, dtype=float),
    }
    return {k: np.clip(np.nan_to_num(v, nan=0.0), -LARGE, LARGE) for k, v in obs.items()}
