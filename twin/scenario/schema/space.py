"""``[space]``: the room, its obstacles, tilted floor, lights and the map it is built from."""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import Field, PrivateAttr, SerializerFunctionWrapHandler, model_serializer

from twin.scenario.limits import (
    MAX_OBSTACLES,
    SITE_SPAN,
    AngleDeg,
    Coordinate,
    Height,
    Point2,
    RoomHeight,
    RoomSpan,
    Size,
)
from twin.scenario.robots import INSTRUMENT_HEIGHT
from twin.scenario.schema.frozen import Frozen, Name


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
    options: dict[Annotated[str, Field(max_length=40)], MapOption] = {}  # noqa: RUF012 (pydantic copies it)


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
