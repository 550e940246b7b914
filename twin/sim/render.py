"""Offscreen rendering of the fixed cameras (pinhole images, OpenCV pixel convention).

Rendering is headless: set ``MUJOCO_GL=egl`` (or ``osmesa``) before importing mujoco.
The image's pixel (row v, column u) is OpenCV's pixel (u, v): row 0 is the top of the
image, as :class:`calib.camera.TsaiCamera` expects.
"""

from __future__ import annotations

from pathlib import Path
from types import TracebackType

import mujoco
import numpy as np
from numpy.typing import NDArray

from twin.sim.scene import World


class CameraRenderer:
    """Renders a world's fixed cameras at their own resolution.

    One :class:`mujoco.Renderer` is kept per distinct resolution. Use as a context manager
    or call :meth:`close`.

    Args:
        world: the world to render (its current state is rendered on each call).
    """

    def __init__(self, world: World) -> None:
        self.world = world
        self._renderers: dict[tuple[int, int], mujoco.Renderer] = {}
        self._option = mujoco.MjvOption()
        # Sites and the collision geoms (group 3) stay hidden; the space (0) and the robots'
        # visual geoms (2) are drawn.
        self._option.geomgroup[:] = [1, 1, 1, 0, 0, 0]
        self._option.sitegroup[:] = [0, 0, 0, 0, 0, 0]

    def render(self, camera: str) -> NDArray[np.uint8]:
        """The camera's current image, (H, W, 3) RGB uint8."""
        m = self.world.model
        cid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, camera)
        if cid < 0:
            raise KeyError(f"no camera {camera!r}; cameras: {', '.join(self.world.camera_names)}")
        w, h = (int(v) for v in m.cam_resolution[cid])
        r = self._renderers.get((w, h))
        if r is None:
            r = mujoco.Renderer(m, height=h, width=w)
            self._renderers[(w, h)] = r
        r.update_scene(self.world.data, camera=cid, scene_option=self._option)
        return r.render().copy()

    def close(self) -> None:
        """Free the rendering contexts."""
        for r in self._renderers.values():
            r.close()
        self._renderers.clear()

    def __enter__(self) -> CameraRenderer:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def save_png(image: NDArray[np.uint8], path: str | Path) -> Path:
    """Write an (H, W, 3) RGB image as PNG and return the path."""
    import cv2

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), np.ascontiguousarray(image[:, :, ::-1])):
        raise OSError(f"could not write {path}")
    return path
