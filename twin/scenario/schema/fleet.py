"""``[robots]`` and ``[marker]``: the parent, its children and the marker assembly the
children carry."""

from __future__ import annotations

import math
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from twin.instruments.marker import MarkerAssembly
from twin.scenario.limits import AngleDeg, Point2
from twin.scenario.robots import PLATFORMS, Platform
from twin.scenario.schema.frozen import Frozen, Name


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
