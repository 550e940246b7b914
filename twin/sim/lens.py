"""Lens distortion and supersampling: remapping a larger, finer pinhole render.

MuJoCo renders pinhole images. A camera with distortion (Tsai's kappa1, or OpenCV's
coefficients) sees, at each pixel of its image, the pinhole image at that pixel's
*undistorted* position. So the camera's image is made by rendering a pinhole image that
covers every undistorted position (a margin around the image where distortion pulls the
view outwards) and remapping it with ``cv2.remap``; the ground truth is the camera model's
own projection, distortion included.

With supersampling ``s``, the pinhole image is rendered ``s`` times finer, remapped at that
resolution, and each output pixel is the mean over its ``s x s`` sub-pixels (the pixel's
area integrated: a small LED's partial coverage of a pixel comes out right).

Coordinates: an output pixel u (OpenCV: pixel centres at integers) covers fine pixels
``s*u .. s*u + s - 1``, whose centres are at ``U = s*u + (s - 1) / 2``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray

from calib.camera import TsaiCamera
from calib.lens_coverage import lens_fold_problem
from calib.opencv_camera import OpenCVCamera
from twin.sim.render import PinholeView

# Extra pinhole pixels kept around the undistorted footprint, for bilinear interpolation.
MARGIN_PAD = 2


def pinhole_intrinsics(camera: TsaiCamera | OpenCVCamera) -> tuple[float, float, float, float]:
    """(fx, fy, cx, cy) of a camera, px: what maps normalised coordinates to pixels."""
    if isinstance(camera, TsaiCamera):
        return camera.sx * camera.f, camera.f, camera.cx, camera.cy
    return camera.fx, camera.fy, camera.cx, camera.cy


def has_distortion(camera: TsaiCamera | OpenCVCamera) -> bool:
    """Whether the camera's model distorts at all."""
    if isinstance(camera, TsaiCamera):
        return camera.kappa1 != 0.0
    return bool(np.any(camera.dist_coeffs != 0.0))


@dataclass(frozen=True, eq=False)
class LensWarp:
    """How to turn one pinhole render into a camera's distorted, pixel-integrated image.

    Attributes:
        view: the pinhole image to render (size, intrinsics).
        image_size: (width, height) of the camera's image, px.
        supersample: fine pixels per output pixel in each direction.
        map_x, map_y: (s*H, s*W) float32 position in ``view``'s pixels of each fine output
            pixel, or None when the remap is the identity (no distortion, no margin).
    """

    view: PinholeView
    image_size: tuple[int, int]
    supersample: int
    map_x: NDArray[np.float32] | None = field(repr=False)
    map_y: NDArray[np.float32] | None = field(repr=False)

    def apply(self, pinhole: NDArray[np.uint8]) -> NDArray[np.float32]:
        """The camera's image from a render of :attr:`view`.

        Args:
            pinhole: (view.height, view.width, 3) uint8 render.

        Returns:
            (H, W, 3) float32 levels on the render's 0..255 scale.
        """
        img = np.asarray(pinhole)
        if img.shape[:2] != (self.view.height, self.view.width):
            raise ValueError(
                f"expected a {self.view.width}x{self.view.height} render, got "
                f"{img.shape[1]}x{img.shape[0]}"
            )
        fine = img.astype(np.float32)
        if self.map_x is not None:
            fine = cv2.remap(
                fine, self.map_x, self.map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
            )
        s = self.supersample
        if s == 1:
            return fine
        w, h = self.image_size
        # Mean over each s x s block: the exact area integral for an integer factor.
        return fine.reshape(h, s, w, s, -1).mean(axis=(1, 3), dtype=np.float32)


def lens_warp(camera: TsaiCamera | OpenCVCamera, supersample: int = 1) -> LensWarp:
    """The pinhole render and remap that give ``camera``'s distorted image.

    Args:
        camera: the camera (its intrinsics and distortion; the pose is not used).
        supersample: fine pixels per output pixel in each direction, 1..8.

    Raises:
        ValueError: a bad supersampling, or a distortion that folds inside the image.
    """
    if not 1 <= int(supersample) <= 8:
        raise ValueError(f"supersample must be an integer from 1 to 8, got {supersample}")
    s = int(supersample)
    problem = lens_fold_problem(camera)
    if problem is not None:
        raise ValueError(problem)
    w, h = camera.image_size
    fx, fy, cx, cy = pinhole_intrinsics(camera)
    distorted = has_distortion(camera)
    if not distorted:
        left = right = top = bottom = 0
    else:
        # The undistorted footprint of the image's outline (its pixels' outer edges).
        edge_u = np.arange(-0.5, w, 1.0)
        edge_v = np.arange(-0.5, h, 1.0)
        outline = np.concatenate(
            [
                np.column_stack([edge_u, np.full_like(edge_u, -0.5)]),
                np.column_stack([edge_u, np.full_like(edge_u, h - 0.5)]),
                np.column_stack([np.full_like(edge_v, -0.5), edge_v]),
                np.column_stack([np.full_like(edge_v, w - 0.5), edge_v]),
                [[w - 0.5, h - 0.5]],
            ]
        )
        uv = _undistorted_pixels(camera, outline, fx, fy, cx, cy)
        left = max(0, math.ceil(-0.5 - uv[:, 0].min())) + MARGIN_PAD
        right = max(0, math.ceil(uv[:, 0].max() - (w - 0.5))) + MARGIN_PAD
        top = max(0, math.ceil(-0.5 - uv[:, 1].min())) + MARGIN_PAD
        bottom = max(0, math.ceil(uv[:, 1].max() - (h - 0.5))) + MARGIN_PAD
    view = PinholeView(
        width=s * (w + left + right),
        height=s * (h + top + bottom),
        fx=s * fx,
        fy=s * fy,
        cx=s * (cx + left) + 0.5 * (s - 1),
        cy=s * (cy + top) + 0.5 * (s - 1),
    )
    if not distorted:
        return LensWarp(view, (w, h), s, None, None)
    # Every fine output pixel's centre, as a (sub-)pixel of the camera's image.
    fu = (np.arange(s * w) - 0.5 * (s - 1)) / s
    fv = (np.arange(s * h) - 0.5 * (s - 1)) / s
    gu, gv = np.meshgrid(fu, fv)
    uv = _undistorted_pixels(camera, np.column_stack([gu.ravel(), gv.ravel()]), fx, fy, cx, cy)
    map_x = (s * (uv[:, 0] + left) + 0.5 * (s - 1)).reshape(s * h, s * w).astype(np.float32)
    map_y = (s * (uv[:, 1] + top) + 0.5 * (s - 1)).reshape(s * h, s * w).astype(np.float32)
    return LensWarp(view, (w, h), s, map_x, map_y)


def _undistorted_pixels(
    camera: TsaiCamera | OpenCVCamera,
    pixels: NDArray[np.float64],
    fx: float,
    fy: float,
    cx: float,
    cy: float,
) -> NDArray[np.float64]:
    """(N, 2) distorted pixels -> (N, 2) pinhole pixels of the same camera (NaN past a fold)."""
    with np.errstate(invalid="ignore"):
        xy = camera.pixels_to_normalized(pixels)
    return np.column_stack([fx * xy[:, 0] + cx, fy * xy[:, 1] + cy])
