"""Conversion between SI camera parameters and the units of the paper's Table II.

Table II reports: focal length / pixel size (px), image centre (px), kappa1 in 1/mm^2 on
the sensor, the camera position in mm and the rotation as angles about X, Y, Z in degrees.
kappa1 in 1/mm^2 needs the sensor's pixel pitch: with r_mm = r_px * pitch_mm,
kappa1_mm = kappa1_px / pitch_mm^2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib.camera import TsaiCamera


@dataclass(frozen=True)
class PaperParameters:
    """A Tsai camera in the units of the paper's Table II.

    Attributes:
        f_px: focal length / pixel size, px.
        cx, cy: image centre, px.
        kappa1_per_mm2: first-order radial distortion, 1/mm^2.
        position_mm: (x, y, z) of the optical centre in the world frame, mm.
        rotation_deg: (rx, ry, rz) Tsai angles about the world X, Y, Z axes, degrees.
        sx: horizontal scale factor.
        pixel_size_mm: sensor pixel pitch used for kappa1, mm.
    """

    f_px: float
    cx: float
    cy: float
    kappa1_per_mm2: float
    position_mm: tuple[float, float, float]
    rotation_deg: tuple[float, float, float]
    sx: float = 1.0
    pixel_size_mm: float = 0.015


def _check_pitch(pixel_size_mm: float) -> None:
    if not (np.isfinite(pixel_size_mm) and pixel_size_mm > 0):
        raise ValueError(f"pixel_size_mm must be a positive number, got {pixel_size_mm}")


def kappa1_px2mm(kappa1_px: float, pixel_size_mm: float) -> float:
    """kappa1 in 1/px^2 -> 1/mm^2 on a sensor with the given pixel pitch (mm)."""
    _check_pitch(pixel_size_mm)
    return kappa1_px / pixel_size_mm**2


def kappa1_mm2px(kappa1_mm: float, pixel_size_mm: float) -> float:
    """kappa1 in 1/mm^2 -> 1/px^2 on a sensor with the given pixel pitch (mm)."""
    _check_pitch(pixel_size_mm)
    return kappa1_mm * pixel_size_mm**2


def to_paper_units(camera: TsaiCamera, pixel_size_mm: float) -> PaperParameters:
    """Express a Tsai camera in Table II's units."""
    return PaperParameters(
        f_px=camera.f,
        cx=camera.cx,
        cy=camera.cy,
        kappa1_per_mm2=kappa1_px2mm(camera.kappa1, pixel_size_mm),
        position_mm=tuple((camera.position * 1e3).tolist()),
        rotation_deg=tuple(np.degrees(camera.rotation_rad).tolist()),
        sx=camera.sx,
        pixel_size_mm=pixel_size_mm,
    )


def from_paper_units(
    params: PaperParameters, image_size: tuple[int, int] = (320, 240)
) -> TsaiCamera:
    """Build a Tsai camera (SI units) from Table II's units."""
    return TsaiCamera.from_pose(
        f=params.f_px,
        cx=params.cx,
        cy=params.cy,
        kappa1=kappa1_mm2px(params.kappa1_per_mm2, params.pixel_size_mm),
        sx=params.sx,
        position=np.asarray(params.position_mm, dtype=float) / 1e3,
        rotation_rad=np.radians(params.rotation_deg),
        image_size=image_size,
    )
