"""How a camera's pose changed: a shift of its optical centre and a turn about its own axes.

One convention, written once, for moving a camera (the twin's moved-camera fault) and for
measuring how far one moved (``twin check``):

- the **shift** is the optical centre's displacement in the world frame, (3,) m:
  ``after.position = before.position + shift``;
- the **turn** is a rotation vector in the camera's own frame (OpenCV axes: x right, y
  down, z forward), (3,) rad: the camera turns by ``|turn|`` about the axis ``turn /
  |turn|`` of its frame before the move, so that
  ``R_cam2world(after) = R_cam2world(before) @ exp(turn)``. For small turns its
  components are the turns about the camera's x (tilt), y (pan) and z (roll) axes.

Intrinsics are not touched: a camera knocked or re-mounted keeps its lens.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.camera import TsaiCamera
from calib.opencv_camera import OpenCVCamera
from calib.rotation import matrix2rotvec, rotvec2matrix

Camera = TsaiCamera | OpenCVCamera


def moved_camera(camera: Camera, shift_m: ArrayLike, turn_rad: ArrayLike) -> Camera:
    """``camera`` with its optical centre shifted and its axes turned.

    Args:
        camera: the camera before the move (Tsai or OpenCV model).
        shift_m: (3,) displacement of the optical centre in the world frame, m.
        turn_rad: (3,) rotation vector in the camera's own frame, rad.

    Returns:
        The same kind of camera, with the same intrinsics, at the new pose.
    """
    shift = _vector(shift_m, "shift_m")
    turn = _vector(turn_rad, "turn_rad")
    world2cam = rotvec2matrix(turn).T @ camera.world2cam_r
    position = camera.position + shift
    return dataclasses.replace(camera, world2cam_r=world2cam, world2cam_t=-world2cam @ position)


def pose_change(before: Camera, after: Camera) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """How the pose changed from ``before`` to ``after``: the inverse of :func:`moved_camera`.

    Returns:
        (3,) shift of the optical centre in the world frame, m; (3,) turn as a rotation
        vector in ``before``'s camera frame, rad.
    """
    shift = after.position - before.position
    turn = matrix2rotvec(before.world2cam_r @ after.world2cam_r.T)
    return shift, turn


def _vector(value: ArrayLike, name: str) -> NDArray[np.float64]:
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        v = np.full(0, np.nan)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}")
    return v
