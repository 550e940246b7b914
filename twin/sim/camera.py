"""MuJoCo cameras <-> Tsai cameras: the frame flip and the principal-point convention.

Frames. OpenCV's camera frame (used by :mod:`calib`) has x right, y down, z forward.
A MuJoCo camera looks along its -z axis with y up. The same physical camera therefore has

    R_cam2world(MuJoCo) = R_cam2world(OpenCV) @ CV2MJ,     CV2MJ = diag(1, -1, -1).

Intrinsics. A MuJoCo camera with ``sensorsize`` set takes its intrinsics from
``focal_pixel`` (fx, fy in px) and ``principal_pixel`` (ppx, ppy in px). Measured by
rendering a small emissive sphere on the optical axis (320x240 and 640x480, integer and
fractional offsets; ``tests/twin/sim/test_camera_projection.py`` keeps checking it), the
principal point lands at OpenCV pixel

    cx = W / 2 - 0.5 - ppx,        cy = H / 2 - 0.5 - ppy.

So MuJoCo measures the image centre W / 2 from the image's edge (its pixel (0, 0) is a
corner), half a pixel away from OpenCV's convention where (0, 0) is the centre of the
top-left pixel; and a positive ``principal_pixel`` moves the principal point left and up.
:func:`principal_pixel_from_opencv` and :func:`opencv_from_principal_pixel` are the only
places this conversion is written.
"""

from __future__ import annotations

import mujoco
import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from calib.camera import TsaiCamera

# OpenCV camera axes expressed in MuJoCo camera axes (and back: it is its own inverse).
CV2MJ = np.diag([1.0, -1.0, -1.0])

# MuJoCo's image centre minus OpenCV's, px (both axes): W / 2 versus (W - 1) / 2.
HALF_PIXEL = 0.5

# Physical size of one pixel on the simulated sensor, m. MuJoCo needs a sensor size to use
# pixel intrinsics; its value cancels out of the projection.
PIXEL_PITCH = 1.0e-5


def principal_pixel_from_opencv(
    cx: float, cy: float, image_size: tuple[int, int]
) -> tuple[float, float]:
    """OpenCV principal point (px) -> MuJoCo ``principal_pixel`` (px)."""
    w, h = image_size
    return (w / 2.0 - HALF_PIXEL - cx, h / 2.0 - HALF_PIXEL - cy)


def opencv_from_principal_pixel(
    ppx: float, ppy: float, image_size: tuple[int, int]
) -> tuple[float, float]:
    """MuJoCo ``principal_pixel`` (px) -> OpenCV principal point (px)."""
    w, h = image_size
    return (w / 2.0 - HALF_PIXEL - ppx, h / 2.0 - HALF_PIXEL - ppy)


def mujoco_cam2world(world2cam_r: NDArray[np.float64]) -> NDArray[np.float64]:
    """(3, 3) OpenCV world-to-camera rotation -> (3, 3) MuJoCo camera-to-world rotation."""
    return np.asarray(world2cam_r, dtype=float).T @ CV2MJ


def opencv_world2cam(mujoco_cam2world_r: NDArray[np.float64]) -> NDArray[np.float64]:
    """(3, 3) MuJoCo camera-to-world rotation -> (3, 3) OpenCV world-to-camera rotation."""
    return (np.asarray(mujoco_cam2world_r, dtype=float) @ CV2MJ).T


def add_camera(body: mujoco.MjsBody, name: str, camera: TsaiCamera) -> mujoco.MjsCamera:
    """Add a fixed camera with ``camera``'s pose and pinhole intrinsics to ``body``.

    Lens distortion (kappa1) is not rendered by MuJoCo and is ignored here.

    Args:
        body: the body to attach to (the world body for a fixed camera); the camera's
            pose is taken as relative to it.
        name: the camera's name.
        camera: pose (world frame) and intrinsics.
    """
    quat_xyzw = Rotation.from_matrix(mujoco_cam2world(camera.world2cam_r)).as_quat()
    w, h = camera.image_size
    ppx, ppy = principal_pixel_from_opencv(camera.cx, camera.cy, camera.image_size)
    return body.add_camera(
        name=name,
        pos=camera.position.tolist(),
        quat=[quat_xyzw[3], *quat_xyzw[:3]],
        resolution=[w, h],
        sensor_size=[w * PIXEL_PITCH, h * PIXEL_PITCH],
        focal_pixel=[camera.sx * camera.f, camera.f],
        principal_pixel=[ppx, ppy],
    )


def tsai_from_model(
    model: mujoco.MjModel, data: mujoco.MjData, name: str, kappa1: float = 0.0
) -> TsaiCamera:
    """Read a camera's pose and intrinsics back from a compiled model.

    Args:
        model, data: the model and its data (after ``mj_forward`` or a step).
        name: the camera's name.
        kappa1: lens distortion to attach (MuJoCo has none), 1/px^2.

    Returns:
        The camera in Tsai's model, pose in the world frame, OpenCV pixel convention.
    """
    cid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, name)
    if cid < 0:
        raise KeyError(f"no camera named {name!r} in the model")
    res = model.cam_resolution[cid].astype(float)
    sensor = model.cam_sensorsize[cid].astype(float)
    if sensor[0] <= 0 or sensor[1] <= 0:
        raise ValueError(f"camera {name!r} has no sensor size, so no pixel intrinsics")
    intr = model.cam_intrinsic[cid].astype(float)
    fx, fy = intr[0] / sensor[0] * res[0], intr[1] / sensor[1] * res[1]
    ppx, ppy = intr[2] / sensor[0] * res[0], intr[3] / sensor[1] * res[1]
    size = (int(res[0]), int(res[1]))
    cx, cy = opencv_from_principal_pixel(ppx, ppy, size)
    world2cam_r = opencv_world2cam(data.cam_xmat[cid].reshape(3, 3))
    pos = data.cam_xpos[cid].copy()
    return TsaiCamera(
        f=fy,
        cx=cx,
        cy=cy,
        kappa1=kappa1,
        sx=fx / fy,
        world2cam_r=_orthonormal(world2cam_r),
        world2cam_t=-_orthonormal(world2cam_r) @ pos,
        image_size=size,
    )


def _orthonormal(r: NDArray[np.float64]) -> NDArray[np.float64]:
    u, _, vt = np.linalg.svd(r)
    return u @ vt
