"""What the agent of :class:`twin.envs.CpsCampaignEnv` observes: a ``Dict`` of ``Box``
spaces, each entry described in :data:`ENTRIES`; everything comes from what the campaign
knows (its estimates and their covariances), nothing from the twin's truth."""

from __future__ import annotations

import math
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
class StationState:
    """What the campaign knows of a calibration station.

    Attributes:
        camera: its camera's index in the site (0 for the first). xy: (2,) m (W).
        route_distance: the parent's travel to it, m. calibrated: whether its camera is.
        here: whether the parent stands at it.
    """

    camera: int
    xy: NDArray[np.float64]
    route_distance: float
    calibrated: bool
    here: bool


def bearing(
    origin: NDArray[np.float64], heading: float, target: NDArray[np.float64]
) -> tuple[float, float, float]:
    """(range m, cos, sin) of ``target`` (2,) seen from ``origin`` (2,) facing ``heading``."""
    d = np.asarray(target[:2], dtype=float) - origin[:2]
    rng = float(np.hypot(d[0], d[1]))
    if rng < 1e-9:
        return 0.0, 1.0, 0.0
    angle = math.atan2(d[1], d[0]) - heading
    return rng, math.cos(angle), math.sin(angle)


def build_observation(
    *,
    decision: str | None,
    parent_xy: NDArray[np.float64],
    parent_yaw: float,
    parent_covariance: NDArray[np.float64],
    children_pose: NDArray[np.float64],
    travel: tuple[float, float, float],
    goal_xy: NDArray[np.float64] | None,
    cameras: list[CameraState],
    max_cameras: int,
    stations: list[StationState],
    max_stations: int,
    free_space: NDArray[np.float64],
) -> dict[str, NDArray[np.float64]]:
    """The observation (see :data:`ENTRIES`), every value finite."""
    scale = np.array([1e3, 1e3, 1e3, 1e3])  # rad -> mrad, m -> mm
    rows = np.zeros((max_cameras, len(CAMERA_COLUMNS)))
    for k, cam in enumerate(cameras):
        rng, c, s = bearing(parent_xy, parent_yaw, cam.position)
        rows[k] = (
            1.0,
            float(cam.calibrated),
            cam.predicted_error,
            cam.transfer_now,
            rng,
            c,
            s,
            float(cam.here),
        )
    table = np.zeros((max_stations, len(STATION_COLUMNS)))
    for k, st in enumerate(stations):
        rng, c, s = bearing(parent_xy, parent_yaw, st.xy)
        table[k] = (
            1.0,
            st.camera + 1,
            float(st.calibrated),
            st.route_distance,
            rng,
            c,
            s,
            float(st.here),
        )
    goal = np.zeros(4)
    if goal_xy is not None:
        goal = np.array([1.0, *bearing(parent_xy, parent_yaw, goal_xy)])
    children = np.zeros((2, 4))
    children[: len(children_pose), :2] = children_pose[:2, :2]
    children[: len(children_pose), 2] = np.cos(children_pose[:2, 2])
    children[: len(children_pose), 3] = np.sin(children_pose[:2, 2])
    obs = {
        "decision": np.array([decision == "leg", decision == "visit"], dtype=float),
        "parent": np.array(
            [parent_xy[0], parent_xy[1], math.cos(parent_yaw), math.sin(parent_yaw)]
        ),
        "parent_covariance": parent_covariance * np.outer(scale, scale),
        "children": children,
        "travel": np.asarray(travel, dtype=float),
        "goal": goal,
        "cameras": rows,
        "stations": table,
        "free_space": np.asarray(free_space, dtype=float),
    }
    return {k: np.clip(np.nan_to_num(v, nan=0.0), -LARGE, LARGE) for k, v in obs.items()}
