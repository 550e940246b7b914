"""Whether a camera's distortion model is one-to-one over its whole image.

A lens model that folds inside the image (Tsai's kappa1 strongly negative, or OpenCV
coefficients far from a real lens) maps two directions to one pixel: an image made or
undistorted with it is silently wrong. Tsai's model folds where d r_u / d r_d = 0, at
r_d = 1 / sqrt(-3 kappa1); OpenCV's has no closed form, so its undistortion is checked by
projecting back.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from calib.camera import TsaiCamera
from calib.opencv_camera import OpenCVCamera, image_grid

# Largest round-trip miss (px) of OpenCV's undistortion that still counts as invertible;
# where the model is one-to-one the round trip is exact to about 1e-9 px.
ROUND_TRIP_PX = 1e-3


def lens_fold_problem(camera: TsaiCamera | OpenCVCamera) -> str | None:
    """Why ``camera``'s distortion is not one-to-one over its image, or None if it is."""
    w, h = camera.image_size
    if isinstance(camera, TsaiCamera):
        if camera.kappa1 >= 0.0:
            return None
        fold = 1.0 / math.sqrt(-3.0 * camera.kappa1)
        du = np.array([-0.5 - camera.cx, w - 0.5 - camera.cx]) / camera.sx
        dv = np.array([-0.5 - camera.cy, h - 0.5 - camera.cy])
        corner = float(np.sqrt((du**2).max() + (dv**2).max()))
        if corner < fold:
            return None
        return (
            f"kappa1 = {camera.kappa1:.3g} 1/px^2 folds the image {fold:.1f} px from the "
            f"image centre, inside the image (its corners are {corner:.1f} px away); "
            "reduce |kappa1|"
        )
    pixels = image_grid(camera.image_size)
    xy = camera.pixels_to_normalized(pixels)
    back, _ = cv2.projectPoints(
        np.column_stack([xy, np.ones(len(xy))]).reshape(-1, 1, 3),
        np.zeros(3),
        np.zeros(3),
        camera.camera_matrix,
        camera.dist_coeffs,
    )
    miss = np.linalg.norm(back.reshape(-1, 2) - pixels, axis=1)
    miss = np.where(np.isfinite(miss), miss, np.inf)
    i = int(np.argmax(miss))
    if miss[i] <= ROUND_TRIP_PX:
        return None
    return (
        f"the OpenCV distortion coefficients are not invertible over the image: pixel "
        f"({pixels[i, 0]:.1f}, {pixels[i, 1]:.1f}) undistorts to a direction that projects "
        f"{miss[i]:.3g} px away (the model folds inside the image)"
    )
