"""Offscreen rendering of the fixed cameras as pinhole images (OpenCV pixel convention).

Rendering is headless (:mod:`twin.sim.gl` picks EGL or OSMesa). The image's pixel (row v,
column u) is OpenCV's pixel (u, v): row 0 is the top of the image, as
:class:`calib.camera.TsaiCamera` expects.

:meth:`CameraRenderer.render` draws a camera as the model defines it. :meth:`render_view`
draws it with other pinhole intrinsics (a larger, finer image for the lens model of
:mod:`twin.sim.lens`) by setting the camera's intrinsics in the model for that one render.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray

from twin.closing import Closing
from twin.sim.camera import PIXEL_PITCH, principal_pixel_from_opencv
from twin.sim.gl import make_renderer
from twin.sim.world import World

# Geom groups drawn: the space (0), test shapes (1) and the robots' visual geoms (2);
# the collision geoms (3) and all sites stay hidden.
VISIBLE_GEOM_GROUPS = (1, 1, 1, 0, 0, 0)


@dataclass(frozen=True)
class PinholeView:
    """Pinhole intrinsics of one rendered image (OpenCV convention, no distortion).

    Attributes:
        width, height: image size, px.
        fx, fy: focal lengths, px. cx, cy: principal point, px ((0, 0) is the centre of
            the top-left pixel).
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float


class CameraRenderer(Closing):
    """Renders a world's fixed cameras.

    One :class:`mujoco.Renderer` is kept per distinct image size. Use as a context
    manager or call :meth:`close`.

    Args:
        world: the world to render (its current state is rendered on each call).
    """

    def __init__(self, world: World) -> None:
        self.world = world
        self._renderers: dict[tuple[int, int], mujoco.Renderer] = {}
        self._option = mujoco.MjvOption()
        self._option.geomgroup[:] = VISIBLE_GEOM_GROUPS
        self._option.sitegroup[:] = [0, 0, 0, 0, 0, 0]

    def _camera_id(self, camera: str) -> int:
        cid = mujoco.mj_name2id(self.world.model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
        if cid < 0:
            raise KeyError(f"no camera {camera!r}; cameras: {', '.join(self.world.camera_names)}")
        return cid

    def _renderer(self, width: int, height: int) -> mujoco.Renderer:
        r = self._renderers.get((width, height))
        if r is None:
            r = make_renderer(self.world.model, height, width)
            self._renderers[(width, height)] = r
        return r

    def render(self, camera: str) -> NDArray[np.uint8]:
        """The camera's current image as the model defines it, (H, W, 3) RGB uint8."""
        cid = self._camera_id(camera)
        w, h = (int(v) for v in self.world.model.cam_resolution[cid])
        r = self._renderer(w, h)
        r.update_scene(self.world.data, camera=cid, scene_option=self._option)
        return r.render().copy()

    def render_view(self, camera: str, view: PinholeView) -> NDArray[np.uint8]:
        """The camera's current image from its pose with ``view``'s intrinsics.

        Returns:
            (view.height, view.width, 3) RGB uint8.
        """
        cid = self._camera_id(camera)
        m = self.world.model
        saved = (
            m.cam_resolution[cid].copy(),
            m.cam_sensorsize[cid].copy(),
            m.cam_intrinsic[cid].copy(),
        )
        ppx, ppy = principal_pixel_from_opencv(view.cx, view.cy, (view.width, view.height))
        try:
            m.cam_resolution[cid] = [view.width, view.height]
            m.cam_sensorsize[cid] = [view.width * PIXEL_PITCH, view.height * PIXEL_PITCH]
            m.cam_intrinsic[cid] = [
                view.fx * PIXEL_PITCH,
                view.fy * PIXEL_PITCH,
                ppx * PIXEL_PITCH,
                ppy * PIXEL_PITCH,
            ]
            r = self._renderer(view.width, view.height)
            r.update_scene(self.world.data, camera=cid, scene_option=self._option)
            return r.render().copy()
        finally:
            m.cam_resolution[cid], m.cam_sensorsize[cid], m.cam_intrinsic[cid] = saved

    def close(self) -> None:
        """Free the rendering contexts."""
        for r in self._renderers.values():
            r.close()
        self._renderers.clear()
