"""The records of a run in, Foxglove's messages out: the same for a run (fed by the log's
recorder as each record is written) and for a replay (fed by the log's messages).

Each record is taken in its logged form (:func:`twin.record.codec.encode`: a dict of JSON
values), so a run and a replay of its log give the same messages. The images the LEDs were
found in are not records: a run hands them in (:meth:`FoxgloveStream.image`), a replay has
none.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from foxglove.messages import Log, LogLevel, Pose, PosesInFrame

from calib.io.camera_files import camera_from_dict
from twin.record.foxglove import frames, images, markers, scene
from twin.record.foxglove.convert import pose, timestamp, vector3, yaw_quaternion

TF = "/foxglove/tf"
SCENE_SITE = "/foxglove/scene/site"
SCENE_CAMERAS = "/foxglove/scene/cameras"
SCENE_POINTS = "/foxglove/scene/points"
SCENE_COVARIANCE = "/foxglove/scene/parent_covariance"
SCENE_SIGHTS = "/foxglove/scene/lines_of_sight"
LOG = "/foxglove/log"
TRACK_ESTIMATE = "/foxglove/track/instrument_estimate"
TRACK_TRUTH = "/foxglove/track/instrument_truth"
SCENE_ROBOTS = "/foxglove/scene/robots"

TOPICS: Mapping[str, str] = {
    TF: "foxglove.FrameTransforms",
    SCENE_SITE: "foxglove.SceneUpdate",
    SCENE_CAMERAS: "foxglove.SceneUpdate",
    SCENE_POINTS: "foxglove.SceneUpdate",
    SCENE_COVARIANCE: "foxglove.SceneUpdate",
    SCENE_SIGHTS: "foxglove.SceneUpdate",
    LOG: "foxglove.Log",
    TRACK_ESTIMATE: "foxglove.PosesInFrame",
    TRACK_TRUTH: "foxglove.PosesInFrame",
    SCENE_ROBOTS: "foxglove.SceneUpdate",
}
"""Every topic a stream writes, with its schema, but for each child's tracks
(:func:`track_topic`) and each camera's image topics
(:func:`twin.record.foxglove.images.camera_topics`: from :meth:`FoxgloveStream.image`, so
only where the run took images)."""


def track_topic(robot: str, which: str) -> str:
    """The topic of a child's track, ``which`` ``estimate`` or ``truth``
    (``foxglove.PosesInFrame``)."""
    return f"/foxglove/track/{robot}_{which}"


# The run's topics this stream reads (written here, not imported, so that the recorder
# does not load the campaign).
META = "/run/meta"
TRUTH_CAMERA = "/truth/camera"
TRUTH_INSTRUMENT = "/truth/instrument"
TRUTH_ROBOT = "/truth/robot"
PARENT_FIX = "/campaign/parent_fix"
POINT = "/campaign/point"
CALIBRATION = "/campaign/calibration"
FAILURE = "/campaign/failure"
EVENT = "/campaign/event"
STAGE = "/campaign/stage"
SKIPPED = "/campaign/skipped_visit"
SHOT = "/total_station/shot"
SHOT_FAILURE = "/total_station/failure"
SUMMARY = "/run/summary"
INSTRUMENT_HEIGHT_M = 0.40
"""The floor below W without a scenario (the instrument's usual height), m."""

Message = tuple[str, Any]
"""A topic and a Foxglove message."""


class FoxgloveStream:
    """Turns a run's records into Foxglove's messages (:data:`TOPICS`).

    Args:
        scenario: the run's scenario (:class:`twin.scenario.Scenario`), for the site, the
            route, the stations and the floor's height; None: none of these (the robots'
            frames are then drawn 0.40 m below W).
    """

    def __init__(self, scenario: Any | None = None) -> None:
        self.scenario = scenario
        self.floor_z = scenario.space.floor_z if scenario is not None else -INSTRUMENT_HEIGHT_M
        self._started = False
        self._instrument: tuple[np.ndarray, float] = (np.zeros(3), 0.0)
        self._points: dict[tuple[str, int], list[tuple[str, dict[str, Any]]]] = {}
        self._counts: dict[str, int] = {}
        self._track: list[Pose] = []
        self._truth_track: list[Pose] = []
        self._observed: dict[str, dict[str, Any]] = {}  # each camera's last LED observation
        self._imaged: dict[str, tuple[float, dict[str, Any]]] = {}  # its last image's
        self._camera_frames: dict[str, str] = {}  # the frame each camera's images are in
        self._built: dict[str, Any] = {}  # each camera as built (its logged model)
        self._calibrated: dict[str, tuple[str, Any]] = {}  # as last calibrated: frame, model
        self._with_images: set[str] = set()  # the cameras that gave an image
        self.parent = scenario.robots.parent.name if scenario is not None else "parent"
        self._tracks: dict[tuple[str, str], list[Pose]] = {}  # the children's, by frame
        self._shown: dict[tuple[str, str], int] = {}  # poses of each track last sent

    def feed(self, topic: str, data: Mapping[str, Any], t: float) -> list[Message]:
        """The messages that the record ``data`` (its logged form) on ``topic`` at ``t`` s
        gives, in order (none for most records)."""
        out: list[Message] = []
        if not self._started:
            self._started = True
            out += self._start()
        handler = _HANDLERS.get(topic)
        if handler is None and topic.startswith("/base/"):
            handler = FoxgloveStream._base
        elif handler is None and topic.startswith("/camera/") and topic.endswith("/leds"):
            handler = FoxgloveStream._observation
        if handler is not None:
            out += handler(self, topic, data, t)
        return out

    def image(self, camera: str, image: Any, t: float) -> list[Message]:
        """The image (an (H, W) or (H, W, 3) array, DN) that ``camera``'s last LED
        observation (its record fed just before) found the LEDs in, at ``t`` s: the JPEG
        and its annotations (the LEDs found, labelled by their index)."""
        topics = images.camera_topics(camera)
        frame = self._camera_frames.get(camera, f"camera/{camera}")
        out: list[Message] = []
        if camera not in self._with_images:  # its calibrations, from its first image on
            self._with_images.add(camera)
            if camera in self._built:
                built = images.calibration(
                    t, frames.camera_frame(camera, "built"), self._built[camera]
                )
                out.append((topics["calibration_built"], built))
            if camera in self._calibrated:
                calibrated = images.calibration(t, *self._calibrated[camera])
                out.append((topics["calibration"], calibrated))
        out.append((topics["image"], images.compressed_image(t, frame, image)))
        obs = self._observed.get(camera)
        if obs is not None:
            self._imaged[camera] = (t, obs)
            out.append((topics["annotations"], self._annotations(t, obs)))
        return out

    def unreadable(self, topic: str, t: float, exc: Exception) -> list[Message]:
        """A line of Foxglove's log saying that the record on ``topic`` at ``t`` s could
        not be drawn, and why."""
        text = f"cannot draw the record on {topic}: {type(exc).__name__}: {exc}"
        return [(LOG, Log(timestamp=timestamp(t), level=LogLevel.Error, message=text, name=topic))]

    # --- handlers ------------------------------------------------------------------------

    def _start(self) -> list[Message]:
        """W (and the map's frame) and the site, at 0."""
        sc = self.scenario
        if sc is None:
            return []
        out: list[Message] = [(SCENE_SITE, scene.update(scene.site_entities(sc)))]
        marker = sc.marker.assembly()
        drawn = [
            markers.marker_entity(0.0, child.name, which, marker)
            for child in sc.robots.children
            for which in ("truth", "estimate")
        ]
        out.append((SCENE_ROBOTS, scene.update(drawn)))
        if sc.space.map is not None:
            out.append((TF, frames.transforms([frames.map_transform(sc.space.map.pose)])))
        return out

    def _truth_camera(self, topic: str, data: Mapping[str, Any], t: float) -> list[Message]:
        name = str(data["name"])
        self._camera_frames[name] = frames.camera_frame(name, "built")
        self._built[name] = data["camera"]
        return self._camera(t, name, "built", data["camera"], scene.BUILT, {"truth": "true"})

    def _calibration(self, topic: str, data: Mapping[str, Any], t: float) -> list[Message]:
        name, visit = str(data["camera"]), int(data["visit"])
        meta = {"sigma_px": data.get("sigma_px"), "points": data.get("points")}
        out = self._camera(t, name, f"visit{visit}", data["camera_model"], scene.CALIBRATED, meta)
        camera = camera_from_dict(data["camera_model"], "calibration")
        recoloured = []
        for id_, p in self._points.get((name, visit), []):
            leds = np.asarray(p["leds_world"], dtype=float).reshape(-1, 3)
            pixels = np.asarray(p["pixels"], dtype=float).reshape(-1, 2)
            res = np.linalg.norm(camera.project_or_nan(leds) - pixels, axis=1)
            recoloured.append(scene.points_entity(t, id_, leds, res))
        if recoloured:
            out.append((SCENE_POINTS, scene.update(recoloured)))
        topics = images.camera_topics(name)
        frame = frames.camera_frame(name, f"visit{visit}")
        self._camera_frames.setdefault(name, frame)
        self._calibrated[name] = (frame, data["camera_model"])
        if name in self._with_images:  # no image, no image channels
            out.append((topics["calibration"], images.calibration(t, frame, data["camera_model"])))
        for _, p in self._points.get((name, visit), []):
            imaged = p.get("_image")
            if imaged is None:
                continue
            stamp, obs = imaged
            leds = np.asarray(_nan(p["leds_world"]), dtype=float).reshape(-1, 3)
            pixels = np.asarray(_nan(p["pixels"]), dtype=float).reshape(-1, 2)
            projected = camera.project_or_nan(leds)
            note = self._note(obs) + f"; visit {visit} calibrated"
            marks = self._annotations(stamp, obs, note, pixels, projected)
            out.append((topics["annotations"], marks))
        return out

    def _observation(self, topic: str, data: Mapping[str, Any], t: float) -> list[Message]:
        """A camera's LED observation: kept for the image that follows it."""
        camera = str(data["camera"])
        self._observed[camera] = dict(data)
        self._imaged.pop(camera, None)
        return []

    @staticmethod
    def _note(obs: Mapping[str, Any]) -> str:
        failures = list(obs["failures"])
        found = sum(f is None for f in failures)
        missed = sorted({str(f) for f in failures if f is not None})
        note = f"{obs['child']}: {found} of {len(failures)} LEDs found"
        return note + (f" ({', '.join(missed)})" if missed else "")

    def _annotations(
        self,
        t: float,
        obs: Mapping[str, Any],
        note: str | None = None,
        pixels: Any = None,
        projected: Any = None,
    ) -> Any:
        detected = np.asarray(_nan(obs["pixels"]), dtype=float).reshape(-1, 2)
        labels = [f"LED {k}" for k in range(len(detected))]
        text = self._note(obs) if note is None else note
        return images.annotations(t, detected, labels, text, pixels, projected)

    def _camera(
        self, t: float, name: str, which: str, model: Any, c: Any, meta: Mapping[str, Any]
    ) -> list[Message]:
        position, rotation = frames.camera_pose(model)
        frame = frames.camera_frame(name, which)
        camera = camera_from_dict(model, frame)
        tf = frames.transforms([frames.transform(t, frame, position, rotation)])
        frustum = scene.frustum_entity(t, f"{name}/{which}", camera, self.floor_z, c, meta)
        return [(TF, tf), (SCENE_CAMERAS, scene.update([frustum]))]

    def _truth_instrument(self, topic: str, data: Mapping[str, Any], t: float) -> list[Message]:
        xyz, yaw = np.asarray(data["translation"], dtype=float), float(data["yaw"])
        self._truth_track.append(_yaw_pose(xyz, yaw))
        tf = frames.transforms([frames.transform(t, frames.INSTRUMENT_TRUTH, xyz, yaw)])
        return [(TF, tf), (TRACK_TRUTH, self._poses(t, self._truth_track))]

    def _truth_robot(self, topic: str, data: Mapping[str, Any], t: float) -> list[Message]:
        robot = str(data["robot"])
        frame = frames.robot_frame(robot, "truth")
        rotation = np.asarray(data["rotation"], dtype=float).reshape(3, 3)
        tf = frames.transform(t, frame, data["translation"], rotation)
        if robot != self.parent:
            track = self._tracks.setdefault((robot, "truth"), [])
            track.append(pose(data["translation"], rotation))
        return [(TF, frames.transforms([tf]))]

    def _child_tracks(self, t: float) -> list[Message]:
        """Each child's tracks that grew since they were last sent, whole."""
        out: list[Message] = []
        for (robot, which), track in self._tracks.items():
            if self._shown.get((robot, which)) != len(track):
                self._shown[(robot, which)] = len(track)
                out.append((track_topic(robot, which), self._poses(t, track)))
        return out

    def _summary(self, topic: str, data: Mapping[str, Any], t: float) -> list[Message]:
        return self._child_tracks(t)

    def _parent_fix(self, topic: str, data: Mapping[str, Any], t: float) -> list[Message]:
        xyz, yaw = np.asarray(data["translation"], dtype=float), float(data["yaw"])
        self._instrument = (xyz, yaw)
        self._track.append(_yaw_pose(xyz, yaw))
        tf = frames.transforms([frames.transform(t, frames.INSTRUMENT_ESTIMATE, xyz, yaw)])
        out: list[Message] = [(TF, tf), (TRACK_ESTIMATE, self._poses(t, self._track))]
        cov = np.asarray(_nan(data["covariance"]), dtype=float).reshape(4, 4)[1:, 1:]
        ellipsoid = scene.ellipsoid_entity(t, f"fix{int(data['index'])}", xyz, cov)
        if ellipsoid is not None:
            out.append((SCENE_COVARIANCE, scene.update([ellipsoid])))
        return out + self._child_tracks(t)

    def _base(self, topic: str, data: Mapping[str, Any], t: float) -> list[Message]:
        """A robot's odometry, a drive's result or a pose the campaign set."""
        odometry = data.get("odometry") if data.get("_type") == "DriveResult" else data
        if not isinstance(odometry, Mapping) or odometry.get("_type") != "OdometryReading":
            return []
        x, y, yaw = (odometry.get(k) for k in ("x", "y", "yaw"))
        if not all(isinstance(v, int | float) for v in (x, y, yaw)):
            return []
        robot = str(odometry["robot"])
        frame = frames.robot_frame(robot)
        tf = frames.transform(t, frame, (x, y, self.floor_z), float(yaw))
        if topic.endswith("/set_pose") and robot != self.parent:  # placed from a measurement
            track = self._tracks.setdefault((robot, "estimate"), [])
            track.append(_yaw_pose(np.array([x, y, self.floor_z], dtype=float), float(yaw)))
        return [(TF, frames.transforms([tf]))]

    def _point(self, topic: str, data: Mapping[str, Any], t: float) -> list[Message]:
        camera, visit = str(data["camera"]), int(data["visit"])
        n = self._count(f"point/{camera}/{visit}")
        id_ = f"{data['dataset']}/{camera}/visit{visit}/{n}"
        imaged = self._imaged.pop(camera, None)
        if data["dataset"] == "visit":
            kept = dict(data)
            if imaged is not None:  # the image of the observation this point is made of
                kept["_image"] = imaged
            self._points.setdefault((camera, visit), []).append((id_, kept))
        leds = np.asarray(_nan(data["leds_world"]), dtype=float).reshape(-1, 3)
        return [(SCENE_POINTS, scene.update([scene.points_entity(t, id_, leds, None)]))]

    def _shot(self, topic: str, data: Mapping[str, Any], t: float) -> list[Message]:
        polar = [data.get(k) for k in ("distance", "horizontal", "zenith")]
        if not all(isinstance(v, int | float) for v in polar):
            return []
        tilt = data.get("tilt") or {}
        roll, pitch = tilt.get("roll"), tilt.get("pitch")
        if not (isinstance(roll, int | float) and isinstance(pitch, int | float)):
            roll = pitch = 0.0
        return self._sight(t, _levelled(*polar, roll, pitch), failed=False)

    def _shot_failure(self, topic: str, data: Mapping[str, Any], t: float) -> list[Message]:
        out = self._log(topic, data, t)
        aim = (data.get("details") or {}).get("aim_level")
        if isinstance(aim, list) and len(aim) == 3 and all(isinstance(v, int | float) for v in aim):
            out += self._sight(t, np.asarray(aim, dtype=float), failed=True)
        return out

    def _sight(self, t: float, point_level: Any, *, failed: bool) -> list[Message]:
        """The line of sight to ``point_level`` (3,) m, in the instrument's levelled frame
        as the latest fix placed it."""
        xyz, yaw = self._instrument
        c, s = math.cos(yaw), math.sin(yaw)
        x, y, z = (float(v) for v in point_level)
        world = (xyz[0] + c * x - s * y, xyz[1] + s * x + c * y, xyz[2] + z)
        id_ = f"shot{self._count('shot')}"
        return [(SCENE_SIGHTS, scene.update([scene.sight_entity(t, id_, xyz, world, failed)]))]

    def _log(self, topic: str, data: Mapping[str, Any], t: float) -> list[Message]:
        """A failure, an event, a stage or a skipped visit as a line of Foxglove's log."""
        kind = str(data.get("kind") or data.get("stage") or data.get("reason") or "")
        if topic in (STAGE, EVENT):
            level = LogLevel.Info
        elif kind == "campaign_aborted":
            level = LogLevel.Error
        else:
            level = LogLevel.Warning
        who = [f"{k}={data[k]}" for k in ("robot", "camera", "visit") if data.get(k)]
        said = str(data.get("message") or data.get("detail") or "")
        text = f"{kind}: {said}" if said else kind
        if who:
            text += f" ({', '.join(who)})"
        return [(LOG, Log(timestamp=timestamp(t), level=level, message=text, name=topic))]

    # --- helpers -------------------------------------------------------------------------

    def _count(self, key: str) -> int:
        n = self._counts.get(key, 0)
        self._counts[key] = n + 1
        return n

    @staticmethod
    def _poses(t: float, track: list[Pose]) -> PosesInFrame:
        return PosesInFrame(timestamp=timestamp(t), frame_id=frames.WORLD, poses=list(track))


def _yaw_pose(xyz: np.ndarray, yaw: float) -> Pose:
    """A pose at ``xyz`` (3,) m turned ``yaw`` rad about z."""
    return Pose(position=vector3(xyz), orientation=yaw_quaternion(yaw))


def _levelled(
    distance: float, horizontal: float, zenith: float, roll: float, pitch: float
) -> tuple[float, float, float]:
    """A shot (m, rad: :mod:`twin.instruments.polar`) as a point of the levelled frame, m,
    with the tilt (rad) it was read with (:func:`twin.instruments.tilt.level_points`;
    written out here: a shot is drawn on every measurement, and arrays of 3 are slow)."""
    sv = math.sin(zenith)
    x, y = distance * sv * math.cos(horizontal), distance * sv * math.sin(horizontal)
    z = distance * math.cos(zenith)
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    return (
        cp * x + sp * sr * y + sp * cr * z,
        cr * y - sr * z,
        -sp * x + cp * sr * y + cp * cr * z,
    )


def _nan(value: Any) -> Any:
    """A logged value with its nulls (NaN, infinity) as NaN."""
    if value is None:
        return np.nan
    if isinstance(value, list):
        return [_nan(v) for v in value]
    return value


_HANDLERS = {
    TRUTH_CAMERA: FoxgloveStream._truth_camera,
    TRUTH_INSTRUMENT: FoxgloveStream._truth_instrument,
    TRUTH_ROBOT: FoxgloveStream._truth_robot,
    PARENT_FIX: FoxgloveStream._parent_fix,
    CALIBRATION: FoxgloveStream._calibration,
    POINT: FoxgloveStream._point,
    SHOT: FoxgloveStream._shot,
    SHOT_FAILURE: FoxgloveStream._shot_failure,
    FAILURE: FoxgloveStream._log,
    EVENT: FoxgloveStream._log,
    STAGE: FoxgloveStream._log,
    SKIPPED: FoxgloveStream._log,
    SUMMARY: FoxgloveStream._summary,
}
