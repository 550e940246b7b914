"""``[[cameras]]``: each fixed camera's pose, intrinsics and image sensor."""

from __future__ import annotations

import math
from typing import Annotated

import numpy as np
from pydantic import Field, ValidationInfo, field_validator, model_validator
from pydantic_core import PydanticCustomError

from calib.camera import TsaiCamera
from calib.lens_coverage import lens_fold_problem
from calib.opencv_camera import OpenCVCamera
from twin.scenario.limits import DirectionComponent, Point3
from twin.scenario.schema.frozen import Frozen, Name

MAX_IMAGE_PX = 4096
"""Widest and highest image, px ("4K"; an image is rendered whole, so it must fit the
renderer's offscreen buffer)."""

MAX_RENDER_PX = 16384
"""Widest and highest render, px. An image is rendered whole at ``supersample`` times its
size, and OpenGL refuses a larger offscreen buffer than its limit: 16384 px for Mesa's
software renderer (llvmpipe, what headless machines without a GPU render with), 32768 px
for most GPUs."""

ImageSide = Annotated[int, Field(ge=8, le=MAX_IMAGE_PX)]
"""A camera image's width or height, px."""


class SensorConfig(Frozen):
    """The image sensor behind a camera's lens; defaults look like a 2007-era 320x240 camera.

    The rendered scene gives each pixel a level in [0, 1] (1: white at full exposure); the
    sensor turns it into ``exposure * level * full_well_e`` photo-electrons, adds photon
    (Poisson) noise and read noise, and quantises to ``bits`` with full scale at the full
    well. The defaults give about 2.4 DN of noise at mid-grey, 0.8 DN at 10 DN and 0.5 DN in
    the dark (8 bits).

    Attributes:
        exposure: exposure relative to the rendered level (2: twice as bright, clipping
            earlier).
        full_well_e: electrons at full scale.
        read_noise_e: read noise, electrons (standard deviation).
        bits: output bits per channel (8: uint8 images; more: uint16).
        blur_sigma_px: standard deviation of the lens and sensor blur, px (0: none).
        supersample: render at this many times the resolution in each direction and
            integrate each pixel's area (sub-pixel fidelity of small LEDs).
        noise: False for noise-free images (quantisation is kept).
    """

    exposure: Annotated[float, Field(gt=0.0, le=20.0)] = 1.0
    full_well_e: Annotated[float, Field(ge=100.0, le=1.0e6)] = 6000.0
    read_noise_e: Annotated[float, Field(ge=0.0, le=1000.0)] = 12.0
    bits: Annotated[int, Field(ge=8, le=16)] = 8
    blur_sigma_px: Annotated[float, Field(ge=0.0, le=5.0)] = 0.5
    supersample: Annotated[int, Field(ge=1, le=8)] = 1
    noise: bool = True


class CameraConfig(Frozen):
    """A fixed camera: pose by position and view direction (image upright), Tsai intrinsics.

    Attributes:
        name: identifier (also the MuJoCo camera name).
        position: (3,) optical centre in the world frame, m.
        view_direction: (3,) direction of the optical axis in the world frame (any length).
        f: focal length, px, 1 to 1e5. A pinhole camera ``w`` px wide with a horizontal
            field of view ``a`` has ``f = w / (2 tan(a / 2))``: an 8 px camera seeing
            150 deg has f = 1.1 px, a 4096 px camera seeing 2.3 deg has f = 1e5 px, and
            no camera of the twin (8-4096 px, one that sees a scene) lies outside that.
        cx, cy: principal point, px (OpenCV: (0, 0) is the centre of the top-left pixel),
            within one widest image (4096 px) of the widest image: -4096 to 8192.
        kappa1: radial distortion, 1/px^2 (Tsai), at most 0.1 either way. The smallest
            image's corners lie 5.7 px from its centre, where kappa1 = 0.1 already moves
            them by three times their distance; larger images take far less (a kappa1 that
            folds the image inside its corners is refused on its own).
        sx: scale factor.
        image_size: (width, height), px.
        opencv_distortion: OpenCV's distortion coefficients (k1, k2, p1, p2[, k3[, k4, k5,
            k6]]) to use instead of kappa1 (which must then be 0); fx = sx * f, fy = f.
            Each at most 1000 either way: they act on normalised coordinates (below 1 for
            a normal lens; a wide lens's rational terms reach a few hundred).
        sensor: the image sensor; it renders the image whole at ``supersample`` times its
            size, at most ``MAX_RENDER_PX`` wide and high.
        led_centroid_px: this camera's own LED centroid error (see
            ``noise.led_centroid_px``), px per coordinate; None (default): the noise
            section's. Cameras of one network differ (their optics, their electronics, the
            light they look into).
    """

    name: Name
    position: Point3
    view_direction: tuple[DirectionComponent, DirectionComponent, DirectionComponent]
    f: Annotated[float, Field(ge=1.0, le=1.0e5)]
    cx: Annotated[float, Field(ge=-MAX_IMAGE_PX, le=2 * MAX_IMAGE_PX)]
    cy: Annotated[float, Field(ge=-MAX_IMAGE_PX, le=2 * MAX_IMAGE_PX)]
    kappa1: Annotated[float, Field(ge=-0.1, le=0.1)] = 0.0
    sx: Annotated[float, Field(gt=0.5, lt=2.0)] = 1.0
    image_size: tuple[ImageSide, ImageSide]
    opencv_distortion: tuple[Annotated[float, Field(ge=-1000.0, le=1000.0)], ...] | None = None
    sensor: SensorConfig = SensorConfig()
    led_centroid_px: Annotated[float, Field(ge=0.0, le=10.0)] | None = None

    @field_validator("sensor")
    @classmethod
    def _render_fits(cls, v: SensorConfig, info: ValidationInfo) -> SensorConfig:
        size = info.data.get("image_size")
        if size is not None and max(size) * v.supersample > MAX_RENDER_PX:
            most = max(1, MAX_RENDER_PX // max(size))
            raise PydanticCustomError(
                "render_too_large",
                f"a {size[0]} x {size[1]} px image supersampled {v.supersample} times is "
                f"rendered {max(size) * v.supersample} px wide, more than the renderer's "
                f"{MAX_RENDER_PX} px",
                {"expected": f"supersample at most {most} for this image"},
            )
        return v

    @field_validator("opencv_distortion")
    @classmethod
    def _opencv_length(cls, v: tuple[float, ...] | None) -> tuple[float, ...] | None:
        if v is not None and len(v) not in (4, 5, 8):
            raise ValueError(f"must have 4, 5 or 8 coefficients, got {len(v)}")
        return v

    @model_validator(mode="after")
    def _one_distortion_model(self) -> CameraConfig:
        if self.opencv_distortion is not None and self.kappa1 != 0.0:
            raise ValueError(
                "give either kappa1 (Tsai) or opencv_distortion, not both: set kappa1 = 0"
            )
        problem = lens_fold_problem(self.lens())
        if problem is not None:
            raise ValueError(problem)
        return self

    @field_validator("view_direction")
    @classmethod
    def _direction_ok(cls, v: tuple[float, float, float]) -> tuple[float, float, float]:
        n = math.sqrt(sum(c * c for c in v))
        if n < 1e-9:
            raise ValueError("must be a non-zero vector")
        if math.hypot(v[0], v[1]) / n < 1e-3:
            raise ValueError("must not be vertical (the image's up direction is undefined)")
        return v

    def tsai(self) -> TsaiCamera:
        """The camera as a :class:`calib.camera.TsaiCamera` (ground truth of the twin)."""
        return TsaiCamera.from_pose(
            f=self.f,
            cx=self.cx,
            cy=self.cy,
            kappa1=self.kappa1,
            sx=self.sx,
            position=self.position,
            view_direction=self.view_direction,
            image_size=self.image_size,
        )

    def lens(self) -> TsaiCamera | OpenCVCamera:
        """The camera with the distortion the twin renders: Tsai's kappa1, or OpenCV's
        coefficients when ``opencv_distortion`` is given (ground truth of the images)."""
        cam = self.tsai()
        if self.opencv_distortion is None:
            return cam
        k = np.array([[self.sx * self.f, 0.0, self.cx], [0.0, self.f, self.cy], [0, 0, 1.0]])
        return OpenCVCamera(
            k, np.asarray(self.opencv_distortion), cam.world2cam_r, cam.world2cam_t, cam.image_size
        )
