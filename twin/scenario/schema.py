"""The scenario's schema: frozen, typed pydantic models.

Units are SI (metres, seconds) except where a field's name says otherwise (``*_deg`` in
degrees, ``*_arcmin`` in arc-minutes, pixels for camera intrinsics). Positions are in the
world frame W: the parent's instrument frame at its first station, z up. The floor lies at
``space.floor_z`` (by default minus the instrument's height above the floor).

This module checks each value on its own (types, ranges, lengths); cross-checks between
sections (a camera inside the space, a route clear of obstacles, a station that sees its
camera's view) live in :mod:`twin.scenario.cross_checks`.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from typing import Annotated, Literal

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    SerializerFunctionWrapHandler,
    ValidationInfo,
    create_model,
    field_validator,
    model_serializer,
    model_validator,
)
from pydantic_core import PydanticCustomError

from calib.camera import TsaiCamera
from calib.lens_coverage import lens_fold_problem
from calib.opencv_camera import OpenCVCamera
from calib.pose_change import moved_camera
from calib.rotation import wrap_angle
from twin.instruments.marker import MarkerAssembly
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec
from twin.scenario.limits import (
    LONGEST_PATH,
    MAX_CAMERAS,
    MAX_OBSTACLES,
    MAX_PEOPLE,
    MAX_VISITS,
    MAX_WAYPOINTS,
    SITE_SPAN,
    AngleDeg,
    Coordinate,
    DirectionComponent,
    Height,
    Point2,
    Point3,
    RoomHeight,
    RoomSpan,
    Seed,
    Size,
)
from twin.scenario.robots import INSTRUMENT_HEIGHT, PLATFORMS, OdometrySpec, Platform

Name = Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]*$", max_length=40)]


class Frozen(BaseModel):
    """Base of every scenario model: immutable, unknown keys rejected, no type coercion,
    no NaN or infinity."""

    model_config = ConfigDict(frozen=True, extra="forbid", strict=True, allow_inf_nan=False)


# -- the space -------------------------------------------------------------------------------
class Obstacle(Frozen):
    """An inaccessible area that blocks robots and lines of sight, standing on the floor.

    Attributes:
        name: identifier (also the MuJoCo geom name prefix).
        kind: ``box`` (a closed structure) or ``stairs`` (steps rising along its local x).
        center: (x, y) of the footprint's centre, m.
        size: (x, y, z) footprint length and width and height, m (0.01 m, a post or a pane
            of glass, up to the largest space's length and the tallest building's height).
        yaw_deg: rotation of the footprint about z, degrees.
        steps: number of steps (stairs only).
    """

    name: Name
    kind: Literal["box", "stairs"] = "box"
    center: Point2
    size: tuple[Size, Size, Height]
    yaw_deg: AngleDeg = 0.0
    steps: Annotated[int, Field(ge=2, le=60)] = 12

    @property
    def yaw(self) -> float:
        """Rotation about z, rad."""
        return math.radians(self.yaw_deg)


class FloorPatch(Frozen):
    """A rectangle of floor tilted by a few arc-minutes (uneven ground).

    The patch is a thin slab whose lowest edge is flush with the floor.

    Attributes:
        name: identifier.
        center: (x, y) of the patch's centre, m.
        size: (x, y) extent, m.
        tilt_arcmin: rotation about the world x and y axes, arc-minutes (|tilt| <= 60).
    """

    name: Name
    center: Point2
    size: tuple[Size, Size]
    tilt_arcmin: tuple[
        Annotated[float, Field(ge=-60.0, le=60.0)], Annotated[float, Field(ge=-60.0, le=60.0)]
    ]

    @property
    def tilt(self) -> tuple[float, float]:
        """Rotation about world x and y, rad."""
        return (
            math.radians(self.tilt_arcmin[0] / 60.0),
            math.radians(self.tilt_arcmin[1] / 60.0),
        )


class Lighting(Frozen):
    """Lights of the space.

    Attributes:
        shadows: whether the lights cast shadows (3-5x slower rendering).
        ambient: ambient light level of the whole scene (MuJoCo's headlight ambient), 0..1.
        diffuse: diffuse level of each overhead point light, 0..1.
        spacing: distance between overhead lights, m (more than 1 m, at most the largest
            space's length: the lights are at most 8 anyway).
        flicker: relative standard deviation of the light level, drawn afresh for every
            captured camera frame (0.05: the level varies by about 5 % between frames).
        drift_per_frame: relative change of the light level from one captured frame to
            the next (-0.1: a light dimming by 10 % a frame).
    """

    shadows: bool = False
    ambient: Annotated[float, Field(ge=0.0, le=1.0)] = 0.4
    diffuse: Annotated[float, Field(ge=0.0, le=1.0)] = 0.6
    spacing: Annotated[float, Field(gt=1.0, le=SITE_SPAN)] = 15.0
    flicker: Annotated[float, Field(ge=0.0, le=0.5)] = 0.0
    drift_per_frame: Annotated[float, Field(ge=-0.5, le=0.5)] = 0.0


MapOption = str | int | float | bool | tuple[str, ...] | dict[str, float]
"""A value of a map reader's keyword option: a unit name, a number, a flag, a list of layer
names, heights by layer name."""


class SpaceMap(Frozen):
    """The map a space's blocked floor is rebuilt from (``[space.map]``, written by
    ``twin site``), instead of its boxes written out.

    The loader reads ``file`` with :func:`twin.planning.maps.load_map` and ``options``,
    refuses it unless its content hashes to ``sha256``, and lays its blocked floor, seen
    from ``pose``, as boxes on a ``resolution`` grid (:func:`twin.planning.boxes.
    boxed_space`, the ceiling at the space's height); they follow the space's own
    ``obstacles``, with no cap on their number.

    Attributes:
        file: the map (a ROS map's YAML, a DXF plan, a mesh), relative to the scenario
            file's folder, or absolute.
        sha256: SHA-256 of the map's content, 64 hex digits: the file's bytes, then those of
            a ROS map's image (or a glTF's external buffers)
            (:func:`twin.planning.map_files.map_sha256`).
        pose: W in the map's frame: the parent's first station (x, y) m and W's x-axis from
            the map's x-axis, degrees counter-clockwise.
        resolution: the grid of the boxes, m.
        options: the reader's keyword options (``units``, ``wall_layers``, ``keep``...).
    """

    file: Annotated[str, Field(min_length=1, max_length=400)]
    sha256: Annotated[str, Field(pattern=r"^[0-9a-f]{64}$")]
    pose: tuple[Coordinate, Coordinate, AngleDeg] = (0.0, 0.0, 0.0)
    resolution: Annotated[float, Field(gt=0.0, le=10.0)] = 0.1
    options: dict[Annotated[str, Field(max_length=40)], MapOption] = {}


class Space(Frozen):
    """The space the robots work in: a rectangular room with walls.

    Attributes:
        size: (x, y, z) inner length, width and height, m: 1 m (the robots must fit) up to
            a few kilometres across (``twin.scenario.limits.SITE_SPAN``) and as high as
            the tallest building (``SITE_HEIGHT``).
        origin: (x, y) world coordinates of the inner corner with the smallest x and y, m.
        floor_z: height of the floor in the world frame, m (the world frame is the
            instrument frame, so the floor is below it).
        wall_thickness: m, 1 cm to 2 m.
        obstacles: inaccessible areas (at most ``MAX_OBSTACLES`` written in the file);
            once loaded, followed by the boxes of ``map``.
        floor_patches: tilted patches of floor (at most ``MAX_OBSTACLES``).
        lighting: the lights.
        map: the map the blocked floor is rebuilt from (None: the obstacles are all
            written in the file). Its boxes are not written back (a dump, the digest):
            the reference, with the map's hash, stands for them.
    """

    size: tuple[RoomSpan, RoomSpan, RoomHeight]
    origin: Point2
    floor_z: Coordinate = -INSTRUMENT_HEIGHT
    wall_thickness: Annotated[float, Field(ge=0.01, le=2.0)] = 0.3
    obstacles: tuple[Obstacle, ...] = Field(default=(), max_length=MAX_OBSTACLES)
    floor_patches: tuple[FloorPatch, ...] = Field(default=(), max_length=MAX_OBSTACLES)
    lighting: Lighting = Lighting()
    map: SpaceMap | None = None
    _map_boxes: int = PrivateAttr(default=0)

    @model_serializer(mode="wrap")
    def _without_map_boxes(self, handler: SerializerFunctionWrapHandler) -> dict:
        """The fields as written: the map's boxes left out (the reference stands for them)."""
        out = handler(self)
        if self._map_boxes and isinstance(out, dict) and "obstacles" in out:
            out["obstacles"] = out["obstacles"][: len(out["obstacles"]) - self._map_boxes]
        return out

    def with_map_boxes(self, boxes: tuple[Obstacle, ...]) -> Space:
        """This space with ``boxes`` (its map's blocked floor) after its own obstacles; they
        are left out of what the space writes back."""
        out = self.model_copy(update={"obstacles": (*self.own_obstacles, *boxes)})
        out._map_boxes = len(boxes)
        return out

    @property
    def own_obstacles(self) -> tuple[Obstacle, ...]:
        """The obstacles written in the file (those of the map left out)."""
        return self.obstacles[: len(self.obstacles) - self._map_boxes]

    @property
    def x_range(self) -> tuple[float, float]:
        """(min, max) of x inside the walls, m."""
        return (self.origin[0], self.origin[0] + self.size[0])

    @property
    def y_range(self) -> tuple[float, float]:
        """(min, max) of y inside the walls, m."""
        return (self.origin[1], self.origin[1] + self.size[1])

    @property
    def z_range(self) -> tuple[float, float]:
        """(floor, ceiling) heights in the world frame, m."""
        return (self.floor_z, self.floor_z + self.size[2])


# -- cameras ---------------------------------------------------------------------------------
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


# -- robots ----------------------------------------------------------------------------------
class RobotConfig(Frozen):
    """A robot and its start pose on the floor.

    Attributes:
        name: identifier; also the prefix of its MuJoCo names (``name/``).
        model: ``pioneer3at`` or ``pioneer3dx``.
        start_xy: (x, y) of the body origin (on the floor under the robot's centre), m.
        start_yaw_deg: heading (x forward) about z, degrees.
    """

    name: Name
    model: Literal["pioneer3at", "pioneer3dx"]
    start_xy: Point2
    start_yaw_deg: AngleDeg = 0.0

    @property
    def start_yaw(self) -> float:
        """Heading, rad."""
        return math.radians(self.start_yaw_deg)

    @property
    def platform(self) -> Platform:
        """Dimensions and motion limits of the robot."""
        return PLATFORMS[self.model]


class Robots(Frozen):
    """The parent robot and its children.

    Attributes:
        parent: the robot carrying the total station.
        children: the robots carrying marker assemblies (two for CPS).
    """

    parent: RobotConfig
    children: tuple[RobotConfig, ...] = Field(min_length=1, max_length=8)

    @field_validator("parent")
    @classmethod
    def _parent_model(cls, v: RobotConfig) -> RobotConfig:
        if v.model != "pioneer3at":
            raise ValueError("the parent must be a pioneer3at (it carries the total station)")
        return v

    @field_validator("children")
    @classmethod
    def _children_model(cls, v: tuple[RobotConfig, ...]) -> tuple[RobotConfig, ...]:
        for child in v:
            if child.model != "pioneer3dx":
                raise ValueError(f"child {child.name!r} must be a pioneer3dx (it has the mast)")
        return v

    @property
    def all(self) -> tuple[RobotConfig, ...]:
        """The parent first, then the children."""
        return (self.parent, *self.children)


# -- marker ----------------------------------------------------------------------------------
_DEFAULT_MARKER = MarkerAssembly()
_ROWS3 = tuple(tuple(float(c) for c in row) for row in _DEFAULT_MARKER.cubes_body)
_ROWS4 = tuple(tuple(float(c) for c in row) for row in _DEFAULT_MARKER.leds_body)

MarkerOffset = Annotated[float, Field(ge=-1.0, le=1.0)]
"""A horizontal coordinate of a point of the marker assembly in the child's body frame, m:
the assembly rides on a Pioneer 3-DX (0.44 m x 0.38 m), so within 1 m of its centre."""

MarkerHeight = Annotated[float, Field(ge=0.25, le=2.5)]
"""The height of a point of the marker assembly above the floor, m: above the robot's
body (0.22 m high), and at most 2.5 m."""

MarkerPoint = tuple[MarkerOffset, MarkerOffset, MarkerHeight]
"""(x, y, z) of a point of the marker assembly in the child's body frame, m."""


class MarkerConfig(Frozen):
    """Geometry of the marker assembly in the child's body frame (m); defaults from
    :class:`twin.instruments.marker.MarkerAssembly`.

    Attributes:
        cubes: three corner-cube reflection points, m.
        leds: four LED centres, m.
        survey_sigma_m: how well these coordinates are known, m (standard deviation of
            each): the campaign's marker fit weighs and tests the cube shots with it. What
            the twin simulates is ``noise.marker_geometry_m``; set this to what you know of
            your assembly. Default 0: exactly.
    """

    cubes: tuple[MarkerPoint, MarkerPoint, MarkerPoint] = _ROWS3  # type: ignore[assignment]
    leds: tuple[MarkerPoint, MarkerPoint, MarkerPoint, MarkerPoint] = _ROWS4  # type: ignore[assignment]
    survey_sigma_m: Annotated[float, Field(ge=0.0, le=0.05)] = 0.0

    @field_validator("cubes")
    @classmethod
    def _not_collinear(
        cls, v: tuple[MarkerPoint, MarkerPoint, MarkerPoint]
    ) -> tuple[MarkerPoint, MarkerPoint, MarkerPoint]:
        p = np.asarray(v, dtype=float)
        if np.linalg.norm(np.cross(p[1] - p[0], p[2] - p[0])) < 1e-4:
            raise ValueError("the three corner cubes must not be collinear")
        return v

    @model_validator(mode="after")
    def _assembly_accepts(self) -> MarkerConfig:
        self.assembly()
        return self

    def assembly(self) -> MarkerAssembly:
        """The geometry as a :class:`MarkerAssembly`."""
        return MarkerAssembly(
            cubes_body=np.asarray(self.cubes, dtype=float),
            leds_body=np.asarray(self.leds, dtype=float),
            survey_sigma=self.survey_sigma_m,
        )


# -- instrument noise: generated from the instrument dataclasses, so they stay in step ------
class _SpecConfig(Frozen):
    """Base of the configs generated from instrument dataclasses (see below)."""

    _spec_cls: typing.ClassVar[type]

    def spec(self) -> typing.Any:
        """The dataclass instance these values describe."""
        return self._spec_cls(**{name: getattr(self, name) for name in type(self).model_fields})

    @model_validator(mode="after")
    def _spec_accepts(self) -> typing.Self:
        # The dataclass's own checks (ranges, consistency) run here, so a bad value is
        # reported with its key in the scenario file.
        self.spec()
        return self


def _model_from_dataclass(
    cls: type,
    name: str,
    doc: str,
    ranges: dict[str, typing.Any],
    base: type[_SpecConfig] = _SpecConfig,
) -> type[_SpecConfig]:
    """A frozen pydantic model called ``name`` (this module's attribute of that name, so
    that scenarios pickle) with the fields, types and defaults of dataclass ``cls``, each
    field constrained by its entry of ``ranges`` (a ``Field(...)``; every field needs one,
    so that a field added to the dataclass gets a range too), on ``base`` (which may add
    checks between the fields)."""
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]
    if set(ranges) != set(names):
        raise TypeError(f"ranges of {name} must name exactly the fields {names}")
    fields: dict[str, typing.Any] = {}
    for f in dataclasses.fields(cls):
        if f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:
            default = Field(default_factory=f.default_factory)
        else:
            default = ...
        fields[f.name] = (Annotated[hints[f.name], ranges[f.name]], default)
    model = create_model(name, __base__=base, __module__=__name__, **fields)
    model.__doc__ = doc
    model._spec_cls = cls
    return model


TotalStationConfig = _model_from_dataclass(
    TotalStationSpec,
    "TotalStationConfig",
    """Total station noise (SI units); fields and defaults of TotalStationSpec.

    Ranges: the paper's instrument (Table I) has 2 mm + 2 ppm and 5 arc-seconds, and
    builders' instruments are a few times worse; noise up to 5 cm, 100 ppm and 1e-3 rad
    (206 arc-seconds), and resolutions up to 1 cm and 1e-3 rad, leave room for stress
    tests (the campaign already fails at a tenth of them). ``pointing_sigma`` (not in
    Table I, default 0) up to 2 cm: a corner cube a centimetre off its axis of aim.
    ``range_min`` is 0.1 m to 100 m;
    ``range_max`` at most 10 km, beyond the diagonal of the largest space (7.1 km; the
    paper's instrument reaches 2.2 km). ``aim_cone`` is 0.01 rad (0.6 deg, a narrow
    automatic aim) up to pi/2 rad.
    """,
    {
        "distance_sigma_const": Field(ge=0.0, le=0.05),
        "distance_sigma_ppm": Field(ge=0.0, le=100.0),
        "angle_sigma": Field(ge=0.0, le=1e-3),
        "distance_resolution": Field(ge=0.0, le=0.01),
        "angle_resolution": Field(ge=0.0, le=1e-3),
        "range_min": Field(ge=0.1, le=100.0),
        "range_max": Field(gt=0.0, le=10_000.0),
        "aim_cone": Field(ge=0.01, lt=0.5 * math.pi),
        "pointing_sigma": Field(ge=0.0, le=0.02),
    },
)


class _InclinometerChecks(_SpecConfig):
    """Base of :data:`InclinometerConfig`: its noise must fit its working range."""

    @model_validator(mode="after")
    def _noise_within_working_range(self) -> typing.Self:
        sigma, working_range = self.sigma, self.working_range  # fields of the model below
        if sigma > 0.1 * working_range:
            raise PydanticCustomError(
                "noise_beyond_range",
                f"sigma = {sigma:g} rad is more than a tenth of working_range = "
                f"{working_range:g} rad: a level instrument would read out of its range",
                {"expected": f"sigma at most {0.1 * working_range:g} rad"},
            )
        return self


InclinometerConfig = _model_from_dataclass(
    InclinometerSpec,
    "InclinometerConfig",
    """Inclination sensor noise (SI units); fields of InclinometerSpec.

    Ranges: ``sigma`` at most 1e-3 rad (the default is 1 arc-second) and at most a tenth of
    ``working_range``, else a level instrument would read beyond its range;
    ``working_range`` 1e-4 rad (21 arc-seconds) to 0.1 rad (5.7 deg; the default is 3
    arc-minutes, floor patches tilt by at most 1 deg).
    """,
    {"sigma": Field(ge=0.0, le=1e-3), "working_range": Field(ge=1e-4, le=0.1)},
    base=_InclinometerChecks,
)
OdometryConfig = _model_from_dataclass(
    OdometrySpec,
    "OdometryConfig",
    """Wheel odometry drift; fields and defaults of OdometrySpec.

    Ranges: each at most 0.1 (10 % relative errors of the wheel radius and the track; 0.1 m
    and 0.1 rad per square-root metre travelled), twenty to a hundred times the defaults.
    """,
    {
        "wheel_scale_sigma": Field(ge=0.0, le=0.1),
        "track_sigma": Field(ge=0.0, le=0.1),
        "distance_noise": Field(ge=0.0, le=0.1),
        "heading_noise": Field(ge=0.0, le=0.1),
    },
)


class StoppingConfig(Frozen):
    """How far from its goal a robot stops (the geometric fidelity's placement error; the
    render fidelity's robots stop where their controller and odometry leave them).

    Attributes:
        sigma_xy: standard deviation of the stop position on each horizontal axis, m.
        sigma_yaw: standard deviation of the stop heading, rad.
    """

    sigma_xy: Annotated[float, Field(ge=0.0, le=1.0)] = 0.02
    sigma_yaw: Annotated[float, Field(ge=0.0, le=0.5)] = 0.017


class Noise(Frozen):
    """Noise of the instruments, the robots and the LED detection.

    Attributes:
        total_station, inclinometer, odometry: the instruments (paper's Table I defaults).
        stopping: the robots' stopping error (geometric fidelity).
        led_detection_px: standard deviation of each coordinate of a detected LED, px, at
            the geometric fidelity (which projects LEDs instead of rendering them). The
            default is what the render fidelity's detector achieves on the twin's 320 x 240
            images (0.05 px RMS per coordinate, measured over 3-14 m).
        marker_geometry_m: standard deviation of each coordinate of each corner cube and
            LED of a built marker assembly from the geometry the campaign uses (``[marker]``),
            m: how well the assembly was surveyed. Each child's assembly gets its own error,
            drawn once per run. Default 0: the assembly is exactly as specified.
        led_centroid_px: standard deviation of each coordinate of a real camera's LED
            centroid beyond what the twin's images and detector reproduce (interlaced or
            analogue capture, compression, blooming, the LED's shape), px, added to every
            detection at every fidelity. Default 0: the camera is as the twin renders it.
        child_creep_m: standard deviation of each horizontal axis of a standing child's
            shift while the parent drives to its next station, m (its tyres settling, its
            mast leaning: :mod:`twin.sim.rig.creep`). It shows in CPS, which measures the
            child before and after the parent's drive. Default 0: children stand still.
    """

    total_station: TotalStationConfig = TotalStationConfig()  # type: ignore[valid-type]
    inclinometer: InclinometerConfig = InclinometerConfig()  # type: ignore[valid-type]
    odometry: OdometryConfig = OdometryConfig()  # type: ignore[valid-type]
    stopping: StoppingConfig = StoppingConfig()
    led_detection_px: Annotated[float, Field(ge=0.0, le=10.0)] = 0.05
    marker_geometry_m: Annotated[float, Field(ge=0.0, le=0.05)] = 0.0
    led_centroid_px: Annotated[float, Field(ge=0.0, le=10.0)] = 0.0
    child_creep_m: Annotated[float, Field(ge=0.0, le=0.05)] = 0.0


# -- route and calibration plan --------------------------------------------------------------
def polyline_length(points: tuple[Point2, ...]) -> float:
    """Length of the polyline through ``points``, m."""
    p = np.asarray(points, dtype=float)
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


Waypoints = Annotated[tuple[Point2, ...], Field(min_length=2, max_length=MAX_WAYPOINTS)]
"""The (x, y) points of a polyline on the floor, m: from 2 to ``MAX_WAYPOINTS``."""


def _path_not_too_long(points: tuple[Point2, ...]) -> tuple[Point2, ...]:
    """``points`` if their polyline is at most ``LONGEST_PATH`` long; a named error else."""
    length = polyline_length(points)
    if length > LONGEST_PATH:
        raise PydanticCustomError(
            "path_too_long",
            f"the path is {length:.0f} m long",
            {"expected": f"a path at most {LONGEST_PATH:.0f} m long"},
        )
    return points


class Route(Frozen):
    """The reference route of the group (the parent's path), a polyline on the floor.

    Attributes:
        waypoints: (x, y) points, m, at least two and at most ``MAX_WAYPOINTS``; the route
            is at most ``LONGEST_PATH`` (10 km) long.
        return_to_start: after the last visit the group drives on to the route's end, the
            parent's start, to close the loop (control points near the start are measured
            again there). The route must end within 0.5 m of the parent's start.
    """

    waypoints: Waypoints
    return_to_start: bool = False

    _not_too_long = field_validator("waypoints")(_path_not_too_long)

    @property
    def length(self) -> float:
        """Length of the polyline, m."""
        return polyline_length(self.waypoints)

    @property
    def turns_deg(self) -> tuple[float, ...]:
        """Heading change at each interior waypoint, degrees (positive = left)."""
        p = np.asarray(self.waypoints, dtype=float)
        d = np.diff(p, axis=0)
        heading = np.arctan2(d[:, 1], d[:, 0])
        turn = wrap_angle(np.diff(heading))
        return tuple(float(t) for t in np.degrees(turn))


class CalibrationVisit(Frozen):
    """One calibration of one camera: where the parent stands while the child moves.

    Attributes:
        camera: name of the camera.
        station: (x, y) of the parent's body origin on the floor, m.
        yaw_deg: parent's heading there, degrees.
    """

    camera: Name
    station: Point2
    yaw_deg: AngleDeg = 0.0


class Calibration(Frozen):
    """The calibration plan.

    Attributes:
        visits: the visits in the order they are made (a camera may be visited again), at
            most ``MAX_VISITS``.
        min_visible_fraction: the least fraction of a camera's floor view that the total
            station must see from the visit's station (line of sight to the corner cubes,
            within range), for the station to be accepted.
    """

    visits: tuple[CalibrationVisit, ...] = Field(min_length=1, max_length=MAX_VISITS)
    min_visible_fraction: Annotated[float, Field(gt=0.0, le=1.0)] = 0.5


class FormationSettings(Frozen):
    """Where the children stop relative to the parent's next station during CPS travel.

    Both children stand ahead of the station along the route, the nearer ``near_gap`` and
    the farther ``near_gap + spacing`` metres on, offset sideways by ``lateral`` (the nearer
    to one side, the farther to the other) so that neither hides the other's prisms. Where
    a position is not free, the planner tries smaller and mirrored offsets.

    Attributes:
        step: the parent's advance per CPS step, m.
        near_gap, spacing, lateral: m.
    """

    step: Annotated[float, Field(gt=0.5, le=50.0)] = 5.0
    near_gap: Annotated[float, Field(gt=1.3, le=50.0)] = 2.5
    spacing: Annotated[float, Field(gt=0.5, le=50.0)] = 2.5
    lateral: Annotated[float, Field(ge=0.0, le=5.0)] = 0.7


class CampaignSettings(Frozen):
    """How the calibration campaign runs (paper Section IV).

    Attributes:
        reference_cameras: cameras for which reference data sets are taken from the
            parent's first station; None: every camera whose floor view the first station
            sees (at least ``calibration.min_visible_fraction`` of it).
        reference_points: LED points in each reference data set (paper: 70).
        station_points: LED points gathered at each calibration station.
        min_points: fewest points a station must yield for the camera to be calibrated.
        formation: the children's places during CPS travel.
        led_sequence: LED switching sequence, ``binary`` (6 frames for 4 LEDs) or
            ``one_at_a_time`` (6 frames).
        lock_retries: further aims after a lost prism lock before a shot is given up.
        pixel_size_mm: the sensor's pixel pitch, for kappa1 in the paper's 1/mm^2: 0.5 um
            (the smallest pixels made are about 0.56 um) to 0.1 mm.
        strategy: the campaign's decisions (visits, legs, data stops) by name:
            ``planned`` (the default: the paper's visits and legs, each camera's data stops
            chosen for accuracy) or ``paper`` (the paper's, its stops too). ``twin run
            --strategy`` overrides it.
        child_creep_m: how far the campaign allows a standing child to move on each
            horizontal axis while the parent drives, m (standard deviation): CPS adds it to
            the children's positions before each of the parent's fixes, in its estimate,
            its consistency test and its covariance. What the twin simulates is
            ``noise.child_creep_m``; set this to what you know of your robots. Default 0.
        data_stops: where a child stops in a camera's view for its data. ``all_leds`` (the
            default): only where all its LEDs show, spread over the view
            (:func:`twin.campaign.plan.view_stops.view_stops`). ``accuracy``: wherever at
            least one LED shows, chosen greedily to lower the predicted covariance of the
            calibrated camera's position (:mod:`twin.campaign.plan.accurate_stops`); a stop
            where only some LEDs are found then gives a point with those (the others'
            failures still journaled). Every fidelity supports both (the batch replays
            each stop with the LEDs its noise-free plan found).
        progress_slack: how many times what a campaign that progresses needs each of its
            loops may take (the legs of a travel, the travels, the stops of a data set, the
            drives) before it ends with the failure ``no_progress``; the bounds are
            :func:`twin.campaign.bounds.campaign_bounds`. From 1 to 100; default 2.
    """

    reference_cameras: tuple[Name, ...] | None = Field(default=None, max_length=MAX_CAMERAS)
    reference_points: Annotated[int, Field(ge=8, le=1000)] = 70
    station_points: Annotated[int, Field(ge=8, le=1000)] = 70
    min_points: Annotated[int, Field(ge=8, le=1000)] = 24
    formation: FormationSettings = FormationSettings()
    led_sequence: Literal["binary", "one_at_a_time"] = "binary"
    lock_retries: Annotated[int, Field(ge=0, le=10)] = 3
    pixel_size_mm: Annotated[float, Field(ge=0.0005, le=0.1)] = 0.015
    strategy: Name = "planned"
    child_creep_m: Annotated[float, Field(ge=0.0, le=0.05)] = 0.0
    data_stops: Literal["all_leds", "accuracy"] = "all_leds"
    progress_slack: Annotated[float, Field(ge=1.0, le=100.0)] = 2.0


TurnDeg = Annotated[float, Field(ge=-180.0, le=180.0)]
"""A component of a rotation vector, degrees: half a turn either way."""


class MovedCamera(Frozen):
    """A camera that was knocked or re-mounted after its calibration: the twin's world
    holds it at this pose (``[[faults.moved_cameras]]``), the scenario's ``[[cameras]]``
    entry keeps the pose it had.

    The convention is :mod:`calib.pose_change`'s: the optical centre moves by ``shift``
    in the world frame, then the camera turns by the rotation vector ``turn_deg`` given in
    its own axes (x right, y down, z forward: for small turns, tilt, pan and roll).

    Attributes:
        camera: the camera's name (one of ``[[cameras]]``).
        shift: (dx, dy, dz) of the optical centre in the world frame, m.
        turn_deg: rotation vector about the camera's own x, y, z axes, degrees.
    """

    camera: Name
    shift: Point3 = (0.0, 0.0, 0.0)
    turn_deg: tuple[TurnDeg, TurnDeg, TurnDeg] = (0.0, 0.0, 0.0)

    def moved(self, camera: TsaiCamera) -> TsaiCamera:
        """``camera`` (the scenario's pose) at this fault's pose."""
        moved = moved_camera(camera, self.shift, np.radians(self.turn_deg))
        assert isinstance(moved, TsaiCamera)
        return moved


class Faults(Frozen):
    """Faults injected into the simulated devices, to see a run cope with them.

    Attributes:
        lost_lock_rate: probability that the total station's automatic aim fails to lock
            a prism it could see (the shot fails as if no prism were in the cone).
        hidden_led_rate: probability that an LED stays dark during one observation (as if
            something hid it from the camera).
        unreachable: (x, y) goals, m, that no robot can reach: a drive to within 0.5 m of
            one stops short, blocked (at most ``MAX_WAYPOINTS``).
        moved_cameras: cameras the twin's world holds away from their scenario pose (at
            most one entry per camera; see :class:`MovedCamera`).
    """

    lost_lock_rate: Annotated[float, Field(ge=0.0, le=1.0)] = 0.0
    hidden_led_rate: Annotated[float, Field(ge=0.0, le=1.0)] = 0.0
    unreachable: tuple[Point2, ...] = Field(default=(), max_length=MAX_WAYPOINTS)
    moved_cameras: tuple[MovedCamera, ...] = Field(default=(), max_length=MAX_CAMERAS)

    def moved_camera(self, name: str) -> MovedCamera | None:
        """The fault that moves camera ``name``, or None."""
        return next((m for m in self.moved_cameras if m.camera == name), None)


class Person(Frozen):
    """A person walking back and forth along a path: a moving distractor for the cameras
    and an obstacle to lines of sight (robots pass through people: no contacts).

    Attributes:
        name: identifier (the MuJoCo body name; geoms ``NAME/legs``, ``NAME/torso``...).
        waypoints: (x, y) points of the path on the floor, m, at least two and at most
            ``MAX_WAYPOINTS``; the person walks to the last one and back, forever. The path
            is 0.1 m to ``LONGEST_PATH`` long.
        speed: walking speed, m/s, from a shuffle (0.1) to a run (3).
        start_offset: distance along the path at time 0, m; at most twice the longest path
            (beyond that the person would only have walked there and back more often).
        height: m.
        shirt_rgb: colour of the shirt, each channel 0..1.
    """

    name: Name
    waypoints: Waypoints
    speed: Annotated[float, Field(ge=0.1, le=3.0)] = 1.2
    start_offset: Annotated[float, Field(ge=0.0, le=2.0 * LONGEST_PATH)] = 0.0
    height: Annotated[float, Field(ge=1.0, le=2.2)] = 1.75
    shirt_rgb: tuple[
        Annotated[float, Field(ge=0.0, le=1.0)],
        Annotated[float, Field(ge=0.0, le=1.0)],
        Annotated[float, Field(ge=0.0, le=1.0)],
    ] = (0.85, 0.85, 0.80)

    _not_too_long = field_validator("waypoints")(_path_not_too_long)

    @property
    def path_length(self) -> float:
        """Length of the path, m."""
        return polyline_length(self.waypoints)

    @model_validator(mode="after")
    def _path_has_length(self) -> Person:
        if self.path_length < 0.1:
            raise ValueError("the path must be at least 0.1 m long")
        return self


class SimConfig(Frozen):
    """Simulation settings.

    Attributes:
        timestep: physics time step, s.
    """

    timestep: Annotated[float, Field(ge=2e-4, le=0.01)] = 0.002


class SiteInfo(Frozen):
    """Where a scenario planned from a map (``twin site``) came from.

    Attributes:
        map: the map file it was planned from (relative to the scenario's folder, or
            absolute).
        map_pose: W in the map's frame: the parent's first station (x, y) m and W's x-axis
            from the map's x-axis, degrees counter-clockwise. A point (x, y) of W is
            ``(X + x cos a - y sin a, Y + x sin a + y cos a)`` in the map.
        resolution: the grid the map's blocked floor was laid on as boxes, m.
    """

    map: Annotated[str, Field(min_length=1, max_length=400)]
    map_pose: tuple[Coordinate, Coordinate, AngleDeg] = (0.0, 0.0, 0.0)
    resolution: Annotated[float, Field(gt=0.0, le=10.0)] = 0.1


class ControlPoint(Frozen):
    """A point the parent measures whenever it stands near it: a prism left on a pole
    (at the start, say) or a surveyed mark. Measured again after a loop, it closes the loop
    in the global adjustment (:mod:`twin.localization.adjustment`).

    Attributes:
        name: identifier.
        position: (x, y, z) of the prism's centre in W, m (where the twin puts it; the
            campaign aims there until it has measured the point).
        surveyed: the position is known (surveyed into W): the adjustment holds it fixed.
            Otherwise only the campaign's own measurements place it.
        sight_radius_m: the parent measures the point from every station within this
            horizontal distance of it, m.
    """

    name: Name
    position: Point3
    surveyed: bool = False
    sight_radius_m: Annotated[float, Field(gt=0.0, le=100.0)] = 8.0


class Scenario(Frozen):
    """A complete scenario. See ``scenarios/paper_hall.toml`` for a documented example.

    Attributes:
        name: identifier.
        description: free text.
        seed: root seed of every random generator of a run, 0 to 2**63 - 1 (see
            ``twin.scenario.limits.MAX_SEED``).
        space, cameras, robots, marker, noise, route, calibration, sim: the sections; at
            most ``MAX_CAMERAS`` cameras.
        people: people walking through the space (distractors), none by default, at most
            ``MAX_PEOPLE``.
        campaign: how the calibration campaign runs.
        control_points: points the parent measures when it passes (none by default; at
            most ``MAX_CAMERAS``): see :class:`ControlPoint`.
        faults: faults injected into the simulated devices (none by default).
        site: where a scenario planned from a map came from, and the map-to-W transform
            (None for a scenario written by hand).
        source: the file it was loaded from (set by the loader).
    """

    name: Name
    description: str = ""
    seed: Seed
    space: Space
    cameras: tuple[CameraConfig, ...] = Field(min_length=1, max_length=MAX_CAMERAS)
    robots: Robots
    marker: MarkerConfig = MarkerConfig()
    noise: Noise = Noise()
    route: Route
    calibration: Calibration
    sim: SimConfig = SimConfig()
    people: tuple[Person, ...] = Field(default=(), max_length=MAX_PEOPLE)
    campaign: CampaignSettings = CampaignSettings()
    control_points: tuple[ControlPoint, ...] = Field(default=(), max_length=MAX_CAMERAS)
    faults: Faults = Faults()
    site: SiteInfo | None = None
    source: str = ""

    def without_noise(self) -> Scenario:
        """The same scenario with every noise source off: a perfect total station (no noise,
        no output rounding) and inclinometer, exact odometry, exact stops, exact LED
        detection at the geometric fidelity, and cameras without sensor noise."""
        ts = dataclasses.replace(
            TotalStationSpec.noiseless(),
            range_min=self.noise.total_station.range_min,
            range_max=self.noise.total_station.range_max,
            aim_cone=self.noise.total_station.aim_cone,
        )
        noise = Noise(
            total_station=TotalStationConfig(**dataclasses.asdict(ts)),
            inclinometer=InclinometerConfig(
                sigma=0.0, working_range=self.noise.inclinometer.working_range
            ),
            odometry=OdometryConfig(
                wheel_scale_sigma=0.0, track_sigma=0.0, distance_noise=0.0, heading_noise=0.0
            ),
            stopping=StoppingConfig(sigma_xy=0.0, sigma_yaw=0.0),
            led_detection_px=0.0,
            marker_geometry_m=0.0,
            led_centroid_px=0.0,
            child_creep_m=0.0,
        )
        cameras = tuple(
            c.model_copy(
                update={
                    "sensor": c.sensor.model_copy(update={"noise": False}),
                    "led_centroid_px": None if c.led_centroid_px is None else 0.0,
                }
            )
            for c in self.cameras
        )
        return self.model_copy(update={"noise": noise, "cameras": cameras})

    def led_centroid_px(self, camera: str) -> float:
        """The LED centroid error of camera ``camera``, px: its own, else the noise
        section's."""
        own = self.camera(camera).led_centroid_px
        return self.noise.led_centroid_px if own is None else own

    def projected_led_px(self, camera: str) -> float:
        """Standard deviation of each coordinate of an LED that camera ``camera`` sees,
        projected instead of rendered (geometric and batch fidelities), px: the detector's
        and the camera's centroid error in quadrature."""
        centroid = self.led_centroid_px(camera)
        if centroid == 0.0:
            return self.noise.led_detection_px
        return math.hypot(self.noise.led_detection_px, centroid)

    def camera(self, name: str) -> CameraConfig:
        """The camera called ``name``; KeyError naming the known cameras otherwise."""
        for cam in self.cameras:
            if cam.name == name:
                return cam
        known = ", ".join(c.name for c in self.cameras)
        raise KeyError(f"no camera {name!r} in scenario {self.name!r}; cameras: {known}")

    def robot(self, name: str) -> RobotConfig:
        """The robot called ``name``; KeyError naming the known robots otherwise."""
        for robot in self.robots.all:
            if robot.name == name:
                return robot
        known = ", ".join(r.name for r in self.robots.all)
        raise KeyError(f"no robot {name!r} in scenario {self.name!r}; robots: {known}")
