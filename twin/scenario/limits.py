"""Plausible ranges of a scenario's numbers, and the constrained types that carry them.

The twin is made for sites such as a town block or a hospital floor: routes of a few
kilometres, a few hundred cameras, spaces up to a few kilometres across and as high as
buildings. A number far outside such a site is a slip (a unit, an exponent, a missing
decimal point), not a site: left alone it makes a run misbehave (in a hall 1e308 m long
the robots sink through a floor the simulator cannot hold, and the total station never
finds a prism; a focal length of 1e308 px overflows the simulator's single-precision
camera). The schema refuses it and the loader names the accepted range. NaN and infinity
are refused everywhere (the schema's models set ``allow_inf_nan=False``).

Ranges that belong to one field are written at that field, with their argument in its
docstring; those shared by many fields are here.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

SITE_SPAN = 5000.0
"""Longest horizontal extent of a space, m. A town block or a hospital floor is a few
hundred metres across; 5 km leaves room for a campus or a long tunnel."""

SITE_HEIGHT = 1000.0
"""Greatest height of a space or an obstacle, m: above the tallest buildings (830 m)."""

SMALLEST_SIZE = 0.01
"""Smallest size of an obstacle or a floor patch, m: a thin post or a pane of glass."""

SMALLEST_ROOM = 1.0
"""Smallest length, width and height of a space, m (the robots must fit in it)."""

LONGEST_PATH = 10_000.0
"""Longest route or walking path, m: a few kilometres, with room to spare (10 km take the
parent robot, at its top speed of 0.7 m/s, four hours)."""

Coordinate = Annotated[float, Field(ge=-SITE_SPAN, le=SITE_SPAN)]
"""A position coordinate in the world frame, m. The world's origin (the parent's start)
lies inside the space, so no point of a space at most ``SITE_SPAN`` across lies farther
than that from it on any axis (and the space is at most ``SITE_HEIGHT`` high)."""

Point2 = tuple[Coordinate, Coordinate]
"""(x, y) on the floor, m."""

Point3 = tuple[Coordinate, Coordinate, Coordinate]
"""(x, y, z) in the world frame, m."""

DirectionComponent = Annotated[float, Field(ge=-2.0 * SITE_SPAN, le=2.0 * SITE_SPAN)]
"""A component of a direction of any length: at most the difference of two coordinates."""

Size = Annotated[float, Field(ge=SMALLEST_SIZE, le=SITE_SPAN)]
"""A horizontal size of something in the space (an obstacle, a floor patch), m."""

Height = Annotated[float, Field(ge=SMALLEST_SIZE, le=SITE_HEIGHT)]
"""A height of something in the space (an obstacle), m."""

RoomSpan = Annotated[float, Field(ge=SMALLEST_ROOM, le=SITE_SPAN)]
"""The length or width of a space, m."""

RoomHeight = Annotated[float, Field(ge=SMALLEST_ROOM, le=SITE_HEIGHT)]
"""The height of a space, m."""

AngleDeg = Annotated[float, Field(ge=-360.0, le=360.0)]
"""A heading or a rotation about z, degrees: one turn either way, so that both the
(-180, 180] and the [0, 360) conventions are accepted."""

MAX_CAMERAS = 1000
"""Most cameras in a scenario: a few hundred, with room to spare."""

MAX_VISITS = 5000
"""Most calibration visits: every camera of the largest network visited five times."""

MAX_WAYPOINTS = 10_000
"""Most waypoints of a route or a walking path: one every metre of the longest path."""

MAX_OBSTACLES = 1000
"""Most obstacles (or floor patches) of a space: the rooms and pillars of a hospital floor
or the buildings of a town block, with room to spare."""

MAX_PEOPLE = 200
"""Most people walking through a space (each is a moving body the simulator updates)."""

MAX_SEED = 2**63 - 1
"""Largest seed. NumPy's ``SeedSequence`` takes any non-negative integer, but TOML's
integers are 64-bit signed: every larger seed would be a file that some TOML readers
refuse, and one that no 64-bit integer column could store."""

Seed = Annotated[int, Field(ge=0, le=MAX_SEED)]
"""A seed of the run's random generators."""


def check_seed(seed: int) -> int:
    """``seed`` as an int if it is a whole number from 0 to :data:`MAX_SEED`.

    Raises:
        ValueError: naming the seed and the range.
    """
    if isinstance(seed, bool) or int(seed) != seed or not 0 <= int(seed) <= MAX_SEED:
        raise ValueError(f"a seed must be a whole number from 0 to 2^63 - 1, got {seed!r}")
    return int(seed)
