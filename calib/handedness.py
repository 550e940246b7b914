"""World frames with one axis reversed (left-handed), and how to calibrate in them.

A survey or a hand-made rig often reverses one axis (x to the west instead of the east, z
down). Points in such a frame are the mirror image of the scene, and no camera, which is a
proper rotation and a translation away from a right-handed frame, projects them to their
pixels: a calibration puts the camera behind its points, or fits badly. Negating one
coordinate makes the frame right-handed again; the camera is calibrated in that mirror
image and mapped back.

Which axis is negated does not matter to the fit: two mirror images, across axes ``a`` and
``b``, differ by a rotation of 180 deg about the third axis, which the camera's pose
absorbs. The camera mapped back to the user's frame is the same whichever axis was
negated, and one mirrored fit tells whether the data are mirrored. Which axis the user
reversed is told only by what the scene looks like (:func:`mirror_hints`): the DESIGN's
world frame has z up, and a camera is normally mounted above what it watches.

A camera in a left-handed frame has no rotation matrix (its world-to-camera map has
determinant -1), so its orientation is given as the directions of its axes in that frame
(:func:`camera_axes`). Everything here is pure numpy: points (N, 3) in any length unit,
directions unit vectors (3,).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

AXES = ("x", "y", "z")

# A calibration whose pixel residual RMS exceeds this is tried mirrored: LED and corner
# detections are good to a fraction of a pixel and hand-picked points to one or two, so
# 5 px is far above the noise of any real correspondence file.
POOR_FIT_RMS_PX = 5.0
# A mirrored fit explains the data when it is not poor and at least this many times better
# than the fit as given (a failed fit is infinitely bad).
MIRROR_GAIN = 4.0
# Height of the camera above the median point, as a fraction of its median distance to
# the points, beyond which it counts as above (or below) them.
ABOVE_MIN = 0.1


class MirroredFrameError(ValueError):
    """Points that fit a camera only in their mirror image: the frame is left-handed (or
    the pixels' v runs upwards). The message says which option to use."""


def axis_index(axis: str) -> int:
    """Index (0, 1, 2) of ``axis`` ("x", "y" or "z"); ValueError naming it otherwise."""
    if axis not in AXES:
        raise ValueError(f"mirror axis must be one of {', '.join(AXES)}, got {axis!r}")
    return AXES.index(axis)


def mirror_points(points: ArrayLike, axis: str | None) -> NDArray[np.float64]:
    """Points or directions with the ``axis`` coordinate negated (a copy; None: unchanged).

    Args:
        points: (N, 3) points (any length unit) or (3,) a point or a direction.
        axis: "x", "y", "z", or None.

    Returns:
        Same shape as ``points``. Mirroring twice across the same axis gives the input back.
    """
    out = np.array(points, dtype=float, copy=True)
    if out.shape[-1:] != (3,):
        raise ValueError(f"points must have 3 coordinates in the last axis, got {out.shape}")
    if axis is not None:
        out[..., axis_index(axis)] *= -1.0
    return out


def camera_axes(world2cam_r: ArrayLike, axis: str | None) -> dict[str, NDArray[np.float64]]:
    """Directions of a camera's axes in the user's frame, from its rotation in the mirror image.

    Args:
        world2cam_r: (3, 3) world-to-camera rotation of the camera calibrated on the points
            mirrored across ``axis`` (OpenCV's camera frame: x right, y down, z forward).
        axis: the axis the points were mirrored across, or None (not mirrored).

    Returns:
        ``image_right``, ``image_down`` and ``optical_axis``: (3,) unit directions in the
        user's frame. With a mirror they form a left-handed triple (right x down = -forward),
        as they must in a left-handed frame.
    """
    r = np.asarray(world2cam_r, dtype=float).reshape(3, 3)
    right, down, forward = (mirror_points(row, axis) for row in r)
    return {"image_right": right, "image_down": down, "optical_axis": forward}


def mirror_hints(camera_position: ArrayLike, points: ArrayLike) -> tuple[str, ...]:
    """What most likely made the points fit only mirrored, from the mirrored fit's camera.

    Assumes the frame's vertical is z and the camera is mounted above what it watches, as
    in the paper's hall (2.5 m up, looking 20 deg down): a camera above its points in the
    user's frame says z is up, so x or y was reversed ("x", "y"; the data cannot tell
    which) or the pixels' v runs upwards ("v": a turned-over image is the mirror image of
    the scene too); a camera below its points says z was reversed ("z"). The image's own
    orientation tells nothing: Tsai's angles of the paper's Table II turn the image's down
    direction upwards for cameras 1 and 2, downwards for camera 3.

    Args:
        camera_position: (3,) the fitted optical centre in the user's frame.
        points: (N, 3) the points in the user's frame (same unit as the position).

    Returns:
        The likely causes: ("x", "y", "v"), ("z",), or all four when the camera is level
        with its points (within ``ABOVE_MIN`` of its median distance to them).
    """
    c = np.asarray(camera_position, dtype=float).reshape(3)
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    reach = float(np.median(np.linalg.norm(p - c, axis=1)))
    height = (c[2] - float(np.median(p[:, 2]))) / reach if reach > 0 else 0.0
    if height > ABOVE_MIN:
        return ("x", "y", "v")
    if height < -ABOVE_MIN:
        return ("z",)
    return ("x", "y", "z", "v")


def is_poor_fit(rms_px: float) -> bool:
    """Whether a calibration's pixel residual RMS (px) is far above any real pixel noise."""
    return not rms_px <= POOR_FIT_RMS_PX  # NaN is poor


def mirror_explains(rms_px: float | None, mirrored_rms_px: float) -> bool:
    """Whether a mirrored fit explains the data better than the fit as given.

    Args:
        rms_px: pixel residual RMS of the fit as given, px; None when it failed.
        mirrored_rms_px: pixel residual RMS of the fit of the mirrored points, px.
    """
    if is_poor_fit(mirrored_rms_px):
        return False
    return rms_px is None or not mirrored_rms_px * MIRROR_GAIN > rms_px
