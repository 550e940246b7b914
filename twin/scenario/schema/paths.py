"""Paths on the floor: the group's ``[route]`` and the ``[[people]]`` walking through the
space."""

from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import Field, field_validator, model_validator
from pydantic_core import PydanticCustomError

from calib.rotation import wrap_angle
from twin.scenario.limits import LONGEST_PATH, MAX_WAYPOINTS, Point2
from twin.scenario.schema.frozen import Frozen, Name


def polyline_length(points: tuple[Point2, ...]) -> float:
    """Length of the polyline through ``points``, m."""
    p = np.asarray(points, dtype=float)
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


Waypoints = Annotated[tuple[Point2, ...], Field(min_length=2, max_length=MAX_WAYPOINTS)]
"""The (x, y) points of a polyline on the floor, m: from 2 to ``MAX_WAYPOINTS``."""


def path_not_too_long(points: tuple[Point2, ...]) -> tuple[Point2, ...]:
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

    _not_too_long = field_validator("waypoints")(path_not_too_long)

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

    _not_too_long = field_validator("waypoints")(path_not_too_long)

    @property
    def path_length(self) -> float:
        """Length of the path, m."""
        return polyline_length(self.waypoints)

    @model_validator(mode="after")
    def _path_has_length(self) -> Person:
        if self.path_length < 0.1:
            raise ValueError("the path must be at least 0.1 m long")
        return self
