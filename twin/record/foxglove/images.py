"""A camera's images in Foxglove's schemas: ``foxglove.CameraCalibration`` (as built and
as calibrated), ``foxglove.CompressedImage`` (JPEG) and ``foxglove.ImageAnnotations`` (the
LEDs found, and the LED points the instrument measured projected through the calibrated
camera, with the residual between them).

Pixels: the project's follow OpenCV ((0, 0) is the centre of the top-left pixel), as do
``CameraCalibration``'s K and P (ROS's ``CameraInfo``); ``ImageAnnotations`` put (0, 0) at
the top-left corner of the top-left pixel, so an annotation is the pixel plus 0.5 px
(:func:`annotation_px`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import cv2
import numpy as np
from foxglove.messages import (
    CameraCalibration,
    CompressedImage,
    ImageAnnotations,
    KeyValuePair,
    Point2,
    PointsAnnotation,
    PointsAnnotationType,
    TextAnnotation,
)
from numpy.typing import ArrayLike, NDArray

from calib.camera import TsaiCamera
from calib.io.camera_files import camera_from_dict
from calib.opencv_camera import tsai2opencv
from twin.record.foxglove.convert import color, timestamp

JPEG_QUALITY = 90
"""The JPEG quality of the images (OpenCV's 0..100)."""
ANNOTATION_OFFSET_PX = 0.5
"""An annotation's coordinate minus the OpenCV pixel it marks, px."""
DETECTED, PROJECTED, RESIDUAL = "detected", "projected", "residual"
"""The ``what`` of each points annotation (its metadata)."""
_DETECTED = color(0.1, 1.0, 0.2)
_PROJECTED = color(1.0, 0.2, 1.0)
_RESIDUAL = color(1.0, 0.9, 0.1)
_TEXT_BACKGROUND = color(0.0, 0.0, 0.0, 0.6)


def camera_topics(camera: str) -> dict[str, str]:
    """A camera's topics, by role (``image``, ``annotations``, ``calibration``: as last
    calibrated, ``calibration_built``: as built), each ``/foxglove/camera/NAME/ROLE``."""
    return {
        role: f"/foxglove/camera/{camera}/{role}"
        for role in ("image", "annotations", "calibration", "calibration_built")
    }


TOPIC_SCHEMAS: Mapping[str, str] = {
    "image": "foxglove.CompressedImage",
    "annotations": "foxglove.ImageAnnotations",
    "calibration": "foxglove.CameraCalibration",
    "calibration_built": "foxglove.CameraCalibration",
}
"""The schema of each role of :func:`camera_topics`."""


def annotation_px(pixels: ArrayLike) -> NDArray[np.float64]:
    """(N, 2) OpenCV pixels as Foxglove's annotation coordinates, px."""
    return np.asarray(pixels, dtype=float).reshape(-1, 2) + ANNOTATION_OFFSET_PX


def calibration(t: float, frame_id: str, camera_model: Mapping[str, Any]) -> CameraCalibration:
    """A logged camera (:func:`calib.io.camera_files.camera_to_dict`) as a calibration at
    ``t`` s: K its intrinsics (fx = sx f, fy = f, cx, cy for Tsai's model), D OpenCV's
    distortion (``plumb_bob``, or ``rational_polynomial`` with 8 coefficients) fitted to
    Tsai's radial distortion over the image (:func:`calib.opencv_camera.tsai2opencv`: Tsai's
    model is not OpenCV's), R the identity, P = [K | 0]."""
    camera = camera_from_dict(camera_model, frame_id)
    cv = tsai2opencv(camera).camera if isinstance(camera, TsaiCamera) else camera
    k = np.asarray(cv.camera_matrix, dtype=float)
    d = np.asarray(cv.dist_coeffs, dtype=float)
    width, height = cv.image_size
    return CameraCalibration(
        timestamp=timestamp(t),
        frame_id=frame_id,
        width=int(width),
        height=int(height),
        distortion_model="rational_polynomial" if d.size == 8 else "plumb_bob",
        D=[float(v) for v in d],
        K=[float(v) for v in k.ravel()],
        R=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        P=[float(v) for v in np.column_stack([k, np.zeros(3)]).ravel()],
    )


def jpeg(image: ArrayLike) -> bytes:
    """An (H, W) or (H, W, 3) RGB image in DN (uint8, or uint16 scaled so that its highest
    value is 255) as JPEG bytes. Raises ValueError for anything else."""
    a = np.asarray(image)
    if a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] != 3) or a.size == 0:
        raise ValueError(f"an image must be (H, W) or (H, W, 3), got {a.shape}")
    if a.dtype == np.uint16:
        top = max(int(a.max()), 255)
        a = (a.astype(np.float32) * (255.0 / top)).round().astype(np.uint8)
    elif a.dtype != np.uint8:
        raise ValueError(f"an image must be uint8 or uint16, got {a.dtype}")
    if a.ndim == 3:
        a = cv2.cvtColor(a, cv2.COLOR_RGB2BGR)
    ok, data = cv2.imencode(".jpg", a, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    if not ok:
        raise ValueError(f"OpenCV could not encode a {a.shape} image as JPEG")
    return data.tobytes()


def compressed_image(t: float, frame_id: str, image: ArrayLike) -> CompressedImage:
    """The image (see :func:`jpeg`) at ``t`` s in the camera frame ``frame_id``."""
    return CompressedImage(
        timestamp=timestamp(t), frame_id=frame_id, data=jpeg(image), format="jpeg"
    )


def annotations(
    t: float,
    detected: ArrayLike,
    labels: Sequence[str],
    note: str,
    pixels: ArrayLike | None = None,
    projected: ArrayLike | None = None,
) -> ImageAnnotations:
    """The annotations of the image at ``t`` s.

    Args:
        detected: (N, 2) where the LEDs were found, px (OpenCV); NaN rows (not found) are
            left out. labels: (N,) each LED's label, drawn beside it.
        note: a line drawn in the image's top-left corner (what the observation found).
        pixels: (M, 2) the pixels of the LED points taken (those of ``detected`` that
            gave a point), px; with ``projected``: (M, 2) the same LEDs' measured world
            points projected through the calibrated camera, px. A line joins each pair
            (the residual). None: the image has no calibration yet.
    """
    det = np.asarray(detected, dtype=float).reshape(-1, 2)
    found = np.all(np.isfinite(det), axis=1)
    marks = [_points(DETECTED, annotation_px(det[found]), _DETECTED, PointsAnnotationType.Points)]
    texts = [
        TextAnnotation(
            timestamp=timestamp(t),
            position=Point2(x=float(p[0]) + 4.0, y=float(p[1]) - 4.0),
            text=str(label),
            font_size=10.0,
            text_color=_DETECTED,
            background_color=_TEXT_BACKGROUND,
        )
        for p, label, ok in zip(annotation_px(det), labels, found, strict=True)
        if ok
    ]
    texts.append(
        TextAnnotation(
            timestamp=timestamp(t),
            position=Point2(x=4.0, y=14.0),
            text=note,
            font_size=12.0,
            text_color=color(1.0, 1.0, 1.0),
            background_color=_TEXT_BACKGROUND,
        )
    )
    if pixels is not None and projected is not None:
        pix = annotation_px(pixels)
        proj = annotation_px(projected)
        both = np.all(np.isfinite(pix), axis=1) & np.all(np.isfinite(proj), axis=1)
        marks.append(_points(PROJECTED, proj[both], _PROJECTED, PointsAnnotationType.Points))
        pairs = np.stack([pix[both], proj[both]], axis=1).reshape(-1, 2)
        marks.append(_points(RESIDUAL, pairs, _RESIDUAL, PointsAnnotationType.LineList))
    return ImageAnnotations(timestamp=timestamp(t), points=marks, texts=texts)


def _points(what: str, xy: NDArray[np.float64], c: Any, kind: Any) -> PointsAnnotation:
    return PointsAnnotation(
        type=kind,
        points=[Point2(x=float(x), y=float(y)) for x, y in xy],
        outline_color=c,
        fill_color=c,
        thickness=5.0 if kind == PointsAnnotationType.Points else 1.0,
        metadata=[KeyValuePair(key="what", value=what)],
    )
