"""Input checks that raise ``ValueError`` naming the problem and the offending number.

Every public function of ``calib`` validates its array inputs with these before doing any
work, so a bad input fails at the boundary with a message a user can act on.
"""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import ArrayLike, NDArray

SPREAD_WARNING = 100.0  # condition number of the point cloud above which we warn
# The widest image side accepted, px: the largest sensors have about 15,000 pixels a side,
# and OpenCV takes image sizes as 32-bit integers.
MAX_IMAGE_SIDE_PX = 100_000


class DegenerateGeometryWarning(UserWarning):
    """The point geometry is not singular but poorly conditioned; results may be inaccurate."""


class InputWarning(UserWarning):
    """The input has a property a user should know of: rows that are exact copies of others,
    or magnitudes a real camera would not produce (coordinates in the wrong unit)."""


def _check_finite(arr: NDArray[np.float64], name: str) -> None:
    bad = ~np.isfinite(arr)
    if bad.any():
        rows = np.unique(np.nonzero(bad)[0])
        raise ValueError(
            f"{name} contains {int(bad.sum())} NaN or inf value(s), first in row {int(rows[0])}"
            f" ({len(rows)} row(s) affected); every coordinate must be finite"
        )


def _check_rows(values: ArrayLike, width: int, name: str) -> NDArray[np.float64]:
    arr = np.asarray(values, dtype=float)
    if arr.ndim == 1 and arr.shape[0] == width:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != width:
        raise ValueError(f"{name} must have shape (N, {width}), got {arr.shape}")
    _check_finite(arr, name)
    return arr


def check_points_3d(points: ArrayLike, name: str = "points_3d") -> NDArray[np.float64]:
    """Return ``points`` as a float array of shape (N, 3), or raise ValueError."""
    return _check_rows(points, 3, name)


def check_pixels(pixels: ArrayLike, name: str = "pixels") -> NDArray[np.float64]:
    """Return ``pixels`` as a float array of shape (N, 2), or raise ValueError."""
    return _check_rows(pixels, 2, name)


def check_correspondences(
    points_3d: ArrayLike, pixels: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Check a set of 3D-2D correspondences: shapes (N, 3) and (N, 2) with the same N."""
    p3 = check_points_3d(points_3d)
    p2 = check_pixels(pixels)
    if p3.shape[0] != p2.shape[0]:
        raise ValueError(
            f"points_3d has {p3.shape[0]} rows but pixels has {p2.shape[0]}; "
            "each 3D point needs exactly one pixel"
        )
    return p3, p2


def check_min_points(n: int, needed: int, what: str) -> None:
    """Raise if ``n`` < ``needed``, saying which stage needs how many and why."""
    if n < needed:
        raise ValueError(f"{what} needs at least {needed} points, got {n}")


def check_image_size(image_size: tuple[int, int]) -> tuple[int, int]:
    """Check an image size (width, height) in pixels: two positive integers, each at most
    ``MAX_IMAGE_SIDE_PX``."""
    try:
        w, h = (int(v) for v in image_size)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"image_size must be (width, height), got {image_size!r}") from None
    if w <= 0 or h <= 0 or (w, h) != tuple(image_size):
        raise ValueError(f"image_size must be two positive integers, got {image_size!r}")
    if max(w, h) > MAX_IMAGE_SIDE_PX:
        raise ValueError(
            f"image_size must be at most {MAX_IMAGE_SIDE_PX} px a side, got {image_size!r}"
        )
    return w, h


def check_pixels_in_image(pixels: NDArray[np.float64], image_size: tuple[int, int]) -> None:
    """Raise if any pixel lies outside the image.

    With OpenCV's convention the image covers [-0.5, W - 0.5] x [-0.5, H - 0.5].
    """
    w, h = check_image_size(image_size)
    outside = (
        (pixels[:, 0] < -0.5)
        | (pixels[:, 0] > w - 0.5)
        | (pixels[:, 1] < -0.5)
        | (pixels[:, 1] > h - 0.5)
    )
    if outside.any():
        i = int(np.argmax(outside))
        raise ValueError(
            f"{int(outside.sum())} pixel(s) lie outside the {w}x{h} image, first in row {i}: "
            f"({pixels[i, 0]:.2f}, {pixels[i, 1]:.2f}); is the image size right?"
        )


def check_spread(points_3d: NDArray[np.float64], *, need_3d: bool, what: str) -> float:
    """Check that points are not collinear (and, if ``need_3d``, not coplanar).

    Returns the condition number (largest / smallest singular value of the centred points
    in the dimensions required). Raises ValueError for a singular geometry and warns with
    :class:`DegenerateGeometryWarning` when the condition number exceeds 100 (the thinnest
    extent of the points is under 1% of the widest).
    """
    centred = points_3d - points_3d.mean(axis=0)
    s = np.linalg.svd(centred, compute_uv=False)
    scale = max(s[0], 1e-300)
    rel = s / scale
    if rel[1] < 1e-9:
        raise ValueError(
            f"{what}: the {len(points_3d)} points are collinear "
            f"(second singular value / first = {rel[1]:.2e}); spread them over the view"
        )
    if need_3d and rel[2] < 1e-9:
        raise ValueError(
            f"{what}: the {len(points_3d)} points are coplanar "
            f"(third singular value / first = {rel[2]:.2e}); this stage needs non-coplanar "
            "points, e.g. LEDs at different heights"
        )
    k = 2 if need_3d else 1
    cond = float(s[0] / s[k])
    if cond > SPREAD_WARNING:
        warnings.warn(
            f"{what}: the points are nearly {'coplanar' if need_3d else 'collinear'} "
            f"(condition number {cond:.3g}); the result may be poorly determined",
            DegenerateGeometryWarning,
            stacklevel=3,
        )
    return cond
