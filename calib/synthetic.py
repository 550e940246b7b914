"""Synthetic cameras and LED data sets like the paper's, for tests, benchmarks and examples.

The cameras take the values of the paper's Table II (read as: position of the optical centre
in the world frame in mm; Tsai angles about X, Y, Z in degrees, world-to-camera), with
image size 320 x 240. The world frame is the parent's instrument frame at its first station,
so the floor lies about 0.38 m below the origin (cameras 2.5 m above the floor sit at
z = 2.1 m).

Table II gives kappa1 as 4.33e-7, 8.08e-8 and 7.02e-7 "1/mm^2". Read in 1/mm^2 with any
plausible pixel pitch (5-15 um) those values bend the image by less than 0.01 px and
could not have been estimated; read in 1/px^2 they bend the image corner by up to ~5 px,
a normal lens. The synthetic cameras use them in 1/px^2, the larger (harder) reading.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from calib.camera import TsaiCamera

FLOOR_Z = -0.383  # floor below the instrument origin, m (2.5 m camera height - 2.117 m)
LED_HEIGHTS = (0.35, 0.65, 0.95, 1.25)  # LED heights above the floor, m

# Table II, first calibration of each camera.
_TABLE_II = {
    1: dict(
        f=770.3, cx=160.0, cy=120.1, kappa1=4.33e-7,
        position=(-3.3551, 10.6255, 2.1174), angles_deg=(115.5, -2.9, 178.2),
    ),
    2: dict(
        f=761.8, cx=170.3, cy=109.1, kappa1=8.08e-8,
        position=(12.5066, -1.1011, 2.0792), angles_deg=(-112.4, 2.9, -1.6),
    ),
    3: dict(
        f=754.2, cx=159.9, cy=120.0, kappa1=7.02e-7,
        position=(42.9006, 9.2982, 2.0756), angles_deg=(-123.5, 2.6, -173.5),
    ),
}  # fmt: skip


def paper_camera(index: int = 1, *, kappa1: float | None = None, sx: float = 1.0) -> TsaiCamera:
    """A 320 x 240 camera with the paper's Table II parameters (camera 1, 2 or 3).

    Args:
        index: which camera of Table II.
        kappa1: override the distortion, 1/px^2.
        sx: horizontal scale factor (Table II does not list it; 1 by default).
    """
    if index not in _TABLE_II:
        raise ValueError(f"the paper has cameras 1, 2 and 3, not {index}")
    p = _TABLE_II[index]
    return TsaiCamera.from_pose(
        f=p["f"],
        cx=p["cx"],
        cy=p["cy"],
        kappa1=p["kappa1"] if kappa1 is None else kappa1,
        sx=sx,
        position=p["position"],
        rotation_rad=np.radians(p["angles_deg"]),
        image_size=(320, 240),
    )


def led_points(
    camera: TsaiCamera,
    n_points: int,
    rng: np.random.Generator,
    *,
    floor_z: float = FLOOR_Z,
    led_heights: tuple[float, ...] = LED_HEIGHTS,
    margin_px: float = 4.0,
    max_range: float = 15.0,
) -> NDArray[np.float64]:
    """World points of LEDs on a child robot standing at random places in the camera's view.

    The robot stands at random floor positions whose LEDs project inside the image (with a
    margin); each position contributes the LEDs that are in view, until ``n_points`` points
    are collected. Points at 4 heights make the set non-coplanar, like the paper's data.

    Args:
        camera: the camera whose view is sampled.
        n_points: number of points to return.
        rng: random generator.
        floor_z: height of the floor in the world frame, m.
        led_heights: heights of the LEDs above the floor, m.
        margin_px: keep projected points this far inside the image, px.
        max_range: farthest floor distance from the camera considered, m.

    Returns:
        (n_points, 3) world points, m.
    """
    w, h = camera.image_size
    origins, dirs = camera.unproject([[-0.5, -0.5], [w - 0.5, -0.5], [-0.5, h - 0.5],
                                      [w - 0.5, h - 0.5], [w / 2, h / 2]])  # fmt: skip
    # The footprint on the floor: intersections of the corner rays (clipped to max_range).
    s = np.where(dirs[:, 2] < 0, (floor_z - origins[:, 2]) / np.minimum(dirs[:, 2], -1e-9), 1e9)
    s = np.minimum(s, max_range)
    foot = origins + s[:, None] * dirs
    lo, hi = foot[:, :2].min(axis=0), foot[:, :2].max(axis=0)
    heights = floor_z + np.asarray(led_heights)
    out: list[NDArray[np.float64]] = []
    count = 0
    for _ in range(100 * n_points):
        xy = rng.uniform(lo, hi)
        pts = np.column_stack([np.tile(xy, (len(heights), 1)), heights])
        pc = camera.to_camera_frame(pts)
        if (pc[:, 2] <= 0.5).any():
            continue
        uv = camera.project(pts)
        inside = (
            (uv[:, 0] > margin_px - 0.5)
            & (uv[:, 0] < w - 0.5 - margin_px)
            & (uv[:, 1] > margin_px - 0.5)
            & (uv[:, 1] < h - 0.5 - margin_px)
        )
        if inside.any():
            out.append(pts[inside])
            count += int(inside.sum())
        if count >= n_points:
            return np.vstack(out)[:n_points]
    raise ValueError(f"could not place {n_points} LED points in the view of the camera")


def points_in_view(
    camera: TsaiCamera,
    n_points: int,
    rng: np.random.Generator,
    *,
    depth_m: tuple[float, float] = (3.0, 15.0),
    margin_px: float = 4.0,
) -> NDArray[np.float64]:
    """World points scattered through the camera's view, drawn all at once.

    Each point lies on the line of sight of a pixel drawn uniformly over the image (inside
    ``margin_px``), at a depth z_c drawn uniformly from ``depth_m``: a cloud that fills the
    view in 3D, for any number of points in time and memory linear in ``n_points`` (unlike
    :func:`led_points`, which places one robot at a time).

    Args:
        camera: the camera whose view is sampled.
        n_points: number of points to return.
        rng: random generator.
        depth_m: (near, far) range of the depth z_c in the camera frame, m.
        margin_px: keep the projected points this far inside the image, px.

    Returns:
        (n_points, 3) world points, m; each projects inside the image.
    """
    w, h = camera.image_size
    lo = margin_px - 0.5
    uv = rng.uniform((lo, lo), (w - 0.5 - margin_px, h - 0.5 - margin_px), (n_points, 2))
    xy = camera.pixels_to_normalized(uv)
    z = rng.uniform(*depth_m, n_points)
    pc = np.column_stack([xy * z[:, None], z])
    return (pc - camera.world2cam_t) @ camera.world2cam_r
