"""A video of a run (``twin run --video FILE.mp4``): an overview camera above the site that
follows the group, with the route and the cameras' frustums (as built and as calibrated)
drawn, one frame per ``period`` seconds of campaign time.

Drawn after the run from its log, so the run itself is the same with or without a video:
the robots stand where the twin's truth last put them (``/truth/robot``; their odometry
where a log has no truth), the frustums are Foxglove's
(:func:`twin.record.foxglove.scene.frustum_points`), and the scenario's
world is rendered by MuJoCo (no shadows or reflections, small frames), written with
OpenCV's writer (``mp4v``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from itertools import pairwise
from pathlib import Path
from typing import Any

import numpy as np

import twin.sim  # noqa: F401  (headless rendering is configured before MuJoCo loads)
from calib.io.camera_files import camera_from_dict
from twin.record import read_log
from twin.record.foxglove.scene import frustum_points
from twin.record.foxglove.stream import CALIBRATION, TRUTH_CAMERA, TRUTH_ROBOT
from twin.scenario import Scenario

FPS = 10
"""Frames per second of the video."""
MAX_VIDEO_S = 120.0
"""The longest video the default period gives, s."""
MIN_PERIOD_S = 1.0
"""The shortest default period, s of campaign time per frame."""
SIZE = (640, 360)
"""Width and height of a frame, px."""
VIEW_DISTANCE_M = 20.0
VIEW_ELEVATION_DEG = -75.0
VIEW_AZIMUTH_DEG = 90.0
LINE_WIDTH_PX = 3.0
ROUTE = (0.2, 0.5, 1.0, 1.0)
BUILT = (0.1, 0.8, 0.2, 1.0)
CALIBRATED = (0.2, 0.4, 1.0, 1.0)

Segment = tuple[np.ndarray, np.ndarray, tuple[float, float, float, float]]
"""Two points (3,) m in W and an RGBA colour."""


def default_period(duration_s: float) -> float:
    """Seconds of campaign time per frame so that ``duration_s`` makes at most
    :data:`MAX_VIDEO_S` of video at :data:`FPS` (and no less than :data:`MIN_PERIOD_S`)."""
    return max(MIN_PERIOD_S, duration_s / (MAX_VIDEO_S * FPS))


class _State:
    """What the log's records say at a moment: the robots' poses and the lines to draw."""

    def __init__(self, sc: Scenario) -> None:
        self.floor_z = sc.space.floor_z
        self.truth: dict[str, tuple[np.ndarray, float]] = {}
        self.estimate: dict[str, tuple[np.ndarray, float]] = {}
        route = [np.array([x, y, self.floor_z + 0.02]) for x, y in sc.route.waypoints]
        self.lines: dict[str, list[Segment]] = {
            "route": [(a, b, ROUTE) for a, b in pairwise(route)]
        }

    def take(self, topic: str, data: dict[str, Any]) -> None:
        """Read one record (its logged form)."""
        if topic == TRUTH_ROBOT:
            rotation = np.asarray(data["rotation"], dtype=float).reshape(3, 3)
            yaw = math.atan2(rotation[1, 0], rotation[0, 0])
            self.truth[str(data["robot"])] = (np.asarray(data["translation"], dtype=float), yaw)
        elif topic.startswith("/base/"):
            odo = data.get("odometry") if data.get("_type") == "DriveResult" else data
            if isinstance(odo, dict) and odo.get("_type") == "OdometryReading":
                xyz = np.array([odo["x"], odo["y"], self.floor_z], dtype=float)
                self.estimate[str(odo["robot"])] = (xyz, float(odo["yaw"]))
        elif topic == TRUTH_CAMERA:
            self._frustum(f"{data['name']}/built", data["camera"], BUILT)
        elif topic == CALIBRATION:
            self._frustum(
                f"{data['camera']}/visit{data['visit']}", data["camera_model"], CALIBRATED
            )

    def _frustum(self, key: str, model: dict[str, Any], rgba: tuple) -> None:
        pts = frustum_points(camera_from_dict(model, key), self.floor_z)
        self.lines[key] = [(pts[i], pts[i + 1], rgba) for i in range(0, len(pts), 2)]

    def robots(self) -> dict[str, tuple[np.ndarray, float]]:
        """Each robot's pose: its truth, else its estimate."""
        return {**self.estimate, **self.truth}


def render_video(
    sc: Scenario,
    log_path: str | Path,
    out: str | Path,
    *,
    period: float | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> int:
    """Write the video of the run whose log is ``log_path`` to ``out`` (MP4).

    Args:
        sc: the run's scenario (its seed the run's: the markers as built).
        period: seconds of campaign time per frame (default: :func:`default_period`).
        progress: called with (frames done, frames) after each frame.

    Returns:
        The number of frames written.
    """
    import cv2
    import mujoco

    from twin.run.runner import built_markers
    from twin.sim.gl import make_renderer
    from twin.sim.render import VISIBLE_GEOM_GROUPS
    from twin.sim.world import build_world

    messages = read_log(log_path).messages
    end = messages[-1].timestamp if messages else 0.0
    period = default_period(end) if period is None else float(period)
    frames = int(end // period) + 1
    state = _State(sc)
    world = build_world(sc, markers=built_markers(sc))
    width, height = SIZE
    renderer = make_renderer(world.model, height, width)
    option = mujoco.MjvOption()
    option.geomgroup[:] = VISIBLE_GEOM_GROUPS
    option.sitegroup[:] = [0] * 6
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.distance, camera.elevation = VIEW_DISTANCE_M, VIEW_ELEVATION_DEG
    camera.azimuth = VIEW_AZIMUTH_DEG
    writer = cv2.VideoWriter(str(out), cv2.VideoWriter_fourcc(*"mp4v"), FPS, (width, height))
    if not writer.isOpened():
        renderer.close()
        raise OSError(f"{out}: OpenCV cannot write an MP4 video here")
    done, i = 0, 0
    try:
        for k in range(frames):
            t = k * period
            while i < len(messages) and messages[i].timestamp <= t:
                state.take(messages[i].topic, messages[i].data)
                i += 1
            robots = state.robots()
            for name, (xyz, yaw) in robots.items():
                if name in world.robots:
                    world.place(name, xyz[:2], yaw, settle=0.0)
            if robots:
                centre = np.mean([xyz for xyz, _ in robots.values()], axis=0)
                camera.lookat[:] = [centre[0], centre[1], sc.space.floor_z]
            renderer.update_scene(world.data, camera=camera, scene_option=option)
            scene = renderer.scene
            scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0
            scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
            for segments in state.lines.values():
                for a, b, rgba in segments:
                    _add_line(scene, a, b, rgba)
            image = cv2.cvtColor(renderer.render(), cv2.COLOR_RGB2BGR)
            label = f"{sc.name}  t = {t:.0f} s"
            cv2.putText(image, label, (10, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 1)
            writer.write(image)
            done += 1
            if progress is not None:
                progress(done, frames)
    finally:
        writer.release()
        renderer.close()
    return done


def _add_line(scene: Any, a: np.ndarray, b: np.ndarray, rgba: tuple) -> None:
    """A line from ``a`` to ``b`` (3,) m in the rendered scene (while there is room)."""
    import mujoco

    if scene.ngeom >= scene.maxgeom:
        return
    geom = scene.geoms[scene.ngeom]
    mujoco.mjv_initGeom(
        geom,
        mujoco.mjtGeom.mjGEOM_LINE,
        np.zeros(3),
        np.zeros(3),
        np.eye(3).ravel(),
        np.asarray(rgba, dtype=np.float32),
    )
    mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_LINE, LINE_WIDTH_PX, a, b)
    scene.ngeom += 1
