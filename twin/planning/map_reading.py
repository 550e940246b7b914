"""What the map readers (:mod:`twin.planning.ros_map`, :mod:`twin.planning.dxf_map`,
:mod:`twin.planning.mesh_map`) share: unit names and scales, and picking the regions of
free floor to keep."""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path

import shapely
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry

from twin.planning.floor_map import MapError

__all__ = [
    "KEEP_CHOICES",
    "UNIT_NAMES",
    "check_keep",
    "enclosed_regions",
    "polygons_of",
    "select_regions",
    "unit_scale",
]

#: Metres per unit, by the names a user may give (``units="mm"``).
UNIT_NAMES: dict[str, float] = {
    "m": 1.0,
    "meter": 1.0,
    "meters": 1.0,
    "metre": 1.0,
    "metres": 1.0,
    "mm": 1e-3,
    "millimeter": 1e-3,
    "millimeters": 1e-3,
    "millimetre": 1e-3,
    "millimetres": 1e-3,
    "cm": 1e-2,
    "centimeter": 1e-2,
    "centimeters": 1e-2,
    "centimetre": 1e-2,
    "centimetres": 1e-2,
    "dm": 0.1,
    "km": 1000.0,
    "in": 0.0254,
    "inch": 0.0254,
    "inches": 0.0254,
    "ft": 0.3048,
    "foot": 0.3048,
    "feet": 0.3048,
    "yd": 0.9144,
    "yard": 0.9144,
    "yards": 0.9144,
}


#: Region selections the readers accept (``keep=``).
KEEP_CHOICES = ("largest", "all")


def unit_scale(units: str | float, file: str | Path, element: str = "units") -> float:
    """Metres per unit of a map.

    Args:
        units: a unit name (``"mm"``, ``"cm"``, ``"m"``, ``"inch"``, ``"ft"``...) or a
            positive number of metres per unit.
        file: the map, for the error.
        element: the option or header field the value came from, for the error.

    Raises:
        MapError: an unknown name or a non-positive or non-finite number.
    """
    if isinstance(units, str):
        scale = UNIT_NAMES.get(units.strip().lower())
        if scale is None:
            raise MapError(
                file,
                f"{element}: unknown unit {units!r}: expected one of "
                f"{', '.join(sorted(set(UNIT_NAMES)))} or metres per unit as a number",
            )
        return scale
    try:
        scale = float(units)
    except (TypeError, ValueError):
        raise MapError(
            file, f"{element}: expected a unit name or metres per unit, got {units!r}"
        ) from None
    if not (math.isfinite(scale) and scale > 0.0):
        raise MapError(file, f"{element}: metres per unit must be positive, got {units!r}")
    return scale


def check_keep(keep: str, file: str | Path) -> None:
    """Raise :class:`MapError` unless ``keep`` is one of :data:`KEEP_CHOICES`."""
    if keep not in KEEP_CHOICES:
        raise MapError(file, f"keep: expected one of {KEEP_CHOICES}, got {keep!r}")


def polygons_of(geometry: BaseGeometry | None) -> list[Polygon]:
    """The polygons in a geometry (a Polygon, MultiPolygon or collection), empty ones
    left out."""
    if geometry is None or geometry.is_empty:
        return []
    if isinstance(geometry, Polygon):
        return [geometry]
    if hasattr(geometry, "geoms"):
        return [p for g in geometry.geoms for p in polygons_of(g)]
    return []


def enclosed_regions(solid: BaseGeometry) -> list[Polygon]:
    """The regions a solid outline encloses: every hole of every polygon of ``solid``,
    minus the parts of ``solid`` that stand inside it (islands).

    Args:
        solid: walls and obstacles, map frame, m (a Polygon or MultiPolygon).

    Returns:
        The enclosed regions, largest first; each a Polygon whose holes are the islands.
    """
    holes = [Polygon(ring) for poly in polygons_of(solid) for ring in poly.interiors]
    if not holes:
        return []
    regions: list[Polygon] = []
    tree = shapely.STRtree(polygons_of(solid))
    solids = tree.geometries
    for hole in holes:
        inside = solids.take(tree.query(hole, predicate="intersects"))
        region = hole.difference(shapely.union_all(inside)) if len(inside) else hole
        regions.extend(polygons_of(region))
    regions.sort(key=lambda p: p.area, reverse=True)
    return regions


def select_regions(
    regions: Iterable[Polygon], keep: str, min_area: float, file: str | Path
) -> tuple[Polygon | MultiPolygon, tuple[str, ...]]:
    """Pick the free floor from candidate regions and say what was left out.

    Args:
        regions: disjoint candidate regions of free floor, map frame, m.
        keep: ``"largest"`` (the largest region only) or ``"all"`` (every region of at
            least ``min_area``; the largest is kept even when it is smaller).
        min_area: regions smaller than this are left out (slivers no robot fits in), m^2.
        file: the map, for the notes and errors.

    Returns:
        ``(free, notes)``: a Polygon (one region) or a MultiPolygon (largest first), and
        the notes counting the regions left out and their area.

    Raises:
        MapError: no region at all.
    """
    ordered = sorted(regions, key=lambda p: p.area, reverse=True)
    if not ordered:
        raise MapError(file, "the map has no free floor")
    if keep == "largest":
        kept, dropped = ordered[:1], ordered[1:]
        why = "not connected to the largest region (keep='largest')"
    else:
        kept = [p for p in ordered if p.area >= min_area] or ordered[:1]
        dropped = ordered[len(kept) :]
        why = f"smaller than min_area = {min_area:g} m^2"
    notes = []
    if dropped:
        notes.append(
            f"{len(dropped)} region(s) of free floor left out, "
            f"{sum(p.area for p in dropped):.4g} m^2 in all: {why}"
        )
    free: Polygon | MultiPolygon = kept[0] if len(kept) == 1 else MultiPolygon(kept)
    return free, tuple(notes)
