"""The ceiling of a planned site: how high the space is, and the cameras checked against it.

A ROS grid or a DXF plan has no height; the ceiling then follows the cameras (the highest
camera plus :data:`CEILING_MARGIN`, at least :data:`LOWEST_CEILING`). A mesh has its own
(its top). A ceiling the user gives replaces either.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from twin.planning.floor_map import FloorMap, MapError

__all__ = ["CEILING_MARGIN", "LOWEST_CEILING", "check_ceiling", "site_ceiling"]

CEILING_MARGIN = 0.5
"""Room above the highest camera when the ceiling follows the cameras, m (a camera hangs
from a bracket below the ceiling)."""

LOWEST_CEILING = 3.0
"""The lowest ceiling that follows the cameras, m (a room's usual height)."""


def site_ceiling(
    floor: FloorMap, cameras: Sequence[Mapping[str, Any]], given: float | None = None
) -> float:
    """The ceiling's height above the floor, m: ``given`` if not None, else the map's own
    (:attr:`FloorMap.height_known`), else the highest camera's height plus
    :data:`CEILING_MARGIN`, at least :data:`LOWEST_CEILING`.

    Args:
        floor: the map. cameras: the cameras file's entries (``position``'s z is the height
            above the floor, m). given: ``--ceiling-height``, m.
    """
    if given is not None:
        return float(given)
    if floor.height_known:
        return float(floor.height)
    highest = max((float(c["position"][2]) for c in cameras), default=0.0)
    return max(LOWEST_CEILING, highest + CEILING_MARGIN)


def check_ceiling(
    floor: FloorMap,
    cameras: Sequence[Mapping[str, Any]],
    ceiling: float,
    given: bool,
) -> None:
    """Refuse the cameras that hang at or above the ceiling (the space would not hold
    them), every one named with its height.

    Args:
        floor: the map (for the error's file and whether the height is the map's own).
        cameras: the cameras file's entries. ceiling: its height above the floor, m.
        given: whether ``ceiling`` is the user's ``--ceiling-height``.

    Raises:
        MapError: naming each camera, its height and the ceiling, and the option.
    """
    high = [c for c in cameras if float(c["position"][2]) >= ceiling]
    if not high:
        return
    listing = ", ".join(f"{c['name']!r} at {float(c['position'][2]):.2f} m" for c in high)
    if given:
        source = "given by --ceiling-height"
    elif floor.height_known:
        source = "the map's own height"
    else:
        source = "the default"
    raise MapError(
        floor.source,
        f"camera(s) {listing} above the floor hang at or above the ceiling, "
        f"{ceiling:.2f} m ({source}); expected every camera below the ceiling: give "
        "--ceiling-height M above the highest camera, or check the cameras' heights "
        "(position's z is the height above the floor, m)",
    )
