"""The world frame W of a run, seen from MuJoCo's frame.

W is the total station's levelled frame at the parent's first station (the paper's
definition): its origin is the instrument's centre there, its z axis is vertical and its x
axis the instrument's horizontal zero direction. The simulation's frame differs from it by
however far the parent settled on its wheels: this transform maps the twin's truth into W,
where the campaign's estimates live.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from calib.camera import TsaiCamera
from calib.opencv_camera import OpenCVCamera
from calib.rotation import rot_z, wrap_angle


@dataclass(frozen=True)
class WorldFrame:
    """W relative to MuJoCo's frame: origin (3,) m and heading yaw, rad."""

    origin: NDArray[np.float64]
    yaw: float

    @classmethod
    def from_instrument(cls, position: ArrayLike, instrument2mujoco: ArrayLike) -> WorldFrame:
        """W from the instrument's (3,) position and (3, 3) rotation at the first station."""
        yaw = Rotation.from_matrix(np.asarray(instrument2mujoco, float)).as_euler("ZYX")[0]
        return cls(np.asarray(position, dtype=float).copy(), float(yaw))

    @property
    def mujoco2w(self) -> NDArray[np.float64]:
        """(3, 3) rotation taking MuJoCo-frame vectors to W."""
        return rot_z(-self.yaw)

    def points(self, points_mujoco: ArrayLike) -> NDArray[np.float64]:
        """(..., 3) MuJoCo-frame points -> W, m."""
        return (np.asarray(points_mujoco, dtype=float) - self.origin) @ self.mujoco2w.T

    def points_to_mujoco(self, points_w: ArrayLike) -> NDArray[np.float64]:
        """(..., 3) W points -> MuJoCo frame, m."""
        return np.asarray(points_w, dtype=float) @ self.mujoco2w + self.origin

    def pose(self, pose_mujoco: ArrayLike) -> NDArray[np.float64]:
        """(3,) planar pose (x, y, yaw) in MuJoCo's frame -> W (body origin on the floor
        keeps its offset below the instrument in z, which a planar pose does not carry)."""
        x, y, yaw = np.asarray(pose_mujoco, dtype=float)
        xy = self.mujoco2w[:2, :2] @ (np.array([x, y]) - self.origin[:2])
        return np.array([xy[0], xy[1], float(wrap_angle(yaw - self.yaw))])

    def pose_to_mujoco(self, pose_w: ArrayLike) -> NDArray[np.float64]:
        """(3,) planar pose in W -> MuJoCo's frame."""
        x, y, yaw = np.asarray(pose_w, dtype=float)
        xy = self.mujoco2w[:2, :2].T @ np.array([x, y]) + self.origin[:2]
        return np.array([xy[0], xy[1], float(wrap_angle(yaw + self.yaw))])

    def camera(self, camera: TsaiCamera | OpenCVCamera) -> TsaiCamera | OpenCVCamera:
        """The same camera with its pose expressed in W."""
        r = camera.world2cam_r @ self.mujoco2w.T
        t = camera.world2cam_t + camera.world2cam_r @ self.origin
        if isinstance(camera, TsaiCamera):
            return TsaiCamera(
                camera.f, camera.cx, camera.cy, camera.kappa1, camera.sx, r, t, camera.image_size
            )
        return OpenCVCamera(camera.camera_matrix, camera.dist_coeffs, r, t, camera.image_size)
