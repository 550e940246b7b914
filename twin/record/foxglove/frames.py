"""``foxglove.FrameTransforms``: the frames of a run, each a child of W.

Frame ids (:func:`robot_frame`, :func:`camera_frame`):

- ``W``, the world frame (the parent's instrument frame at its first station); ``map``
  (W's parent, where the site came from a map: W's pose in the map's frame).
- ``ROBOT/estimate``: each robot's base as its localisation knows it (its odometry, drive
  results and the poses the campaign sets), on the floor; ``ROBOT/truth``: its base body
  where it truly is (the twin's truth, at the start and after each drive).
- ``instrument/estimate``: the total station's centre and heading as the campaign fixed it
  (each CPS fix); ``instrument/truth``: the same in the twin's truth (a simulated run).
- ``camera/NAME/built``: the camera as built (the twin's truth; a real run's log has
  none); ``camera/NAME/visitK``: as calibrated at its K-th visit. Camera frames are optical
  frames: x right, y down, z along the optical axis, as Foxglove's camera panels want.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from foxglove.messages import FrameTransform, FrameTransforms
from numpy.typing import ArrayLike, NDArray

from twin.record.foxglove.convert import quaternion, timestamp, vector3, yaw_quaternion

WORLD = "W"
MAP = "map"
INSTRUMENT_ESTIMATE = "instrument/estimate"
INSTRUMENT_TRUTH = "instrument/truth"


def robot_frame(robot: str, which: str = "estimate") -> str:
    """The frame of a robot's base: ``estimate`` (as its localisation knows it) or
    ``truth``."""
    return f"{robot}/{which}"


def camera_frame(camera: str, which: str) -> str:
    """A camera's frame: ``which`` is ``built`` or ``visitK``."""
    return f"camera/{camera}/{which}"


def transform(
    t: float, child: str, translation: ArrayLike, rotation: Any, parent: str = WORLD
) -> FrameTransform:
    """``child`` in ``parent`` at ``t`` s: ``translation`` (3,) m and ``rotation`` a yaw,
    rad (float), or a (3, 3) matrix (child to parent)."""
    q = yaw_quaternion(float(rotation)) if np.ndim(rotation) == 0 else quaternion(rotation)
    return FrameTransform(
        timestamp=timestamp(t),
        parent_frame_id=parent,
        child_frame_id=child,
        translation=vector3(translation),
        rotation=q,
    )


def transforms(items: Sequence[FrameTransform]) -> FrameTransforms:
    """Several transforms as one message."""
    return FrameTransforms(transforms=list(items))


def camera_pose(camera_model: Mapping[str, Any]) -> tuple[NDArray[np.float64], NDArray]:
    """A logged camera (:func:`calib.io.camera_files.camera_to_dict`) as its optical centre
    (3,) m in W and its camera-to-W rotation (3, 3)."""
    r = np.asarray(camera_model["world2cam_r"], dtype=float).reshape(3, 3)
    t = np.asarray(camera_model["world2cam_t"], dtype=float).reshape(3)
    return -r.T @ t, r.T


def map_transform(map_pose: Sequence[float]) -> FrameTransform:
    """W in the map's frame from a scenario's ``space.map.pose`` ((x, y) m, yaw deg)."""
    x, y, yaw_deg = (float(v) for v in map_pose)
    return transform(0.0, WORLD, (x, y, 0.0), math.radians(yaw_deg), parent=MAP)
