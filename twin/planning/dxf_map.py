"""A CAD floor plan (DXF, read with ezdxf) as a :class:`~twin.planning.floor_map.FloorMap`.

What is read, in the drawing's model space (block references are exploded, and an
entity on layer ``0`` inside a block takes the reference's layer):

- wall layers (by default every layer whose name holds a word for walls, any case:
  ``wall`` anywhere in it, as in the AIA's ``A-WALL``, or one of :data:`WALL_WORDS`, the
  German, French, Spanish and Italian words, as a word of the name; German compounds
  ending in one, ``Innenwand``, count too): lines,
  polylines (open or closed), arcs, circles, ellipses and splines are wall centre lines,
  thickened by ``wall_thickness`` (flat ends, so a door left open in the drawing stays as
  wide as drawn);
- obstacle layers (by default names containing ``obstacle``, ``column``, ``pillar`` or
  ``furniture``): closed polylines, circles, closed ellipses and splines are footprints;
  open ones are thickened like walls;
- everything else, and other entity types (text, dimensions, hatches...) on those
  layers, is not geometry of the floor: the notes count what was passed over.

The free floor is the largest region the walls enclose (a hole of the thickened walls'
union), minus every wall and obstacle inside it. Coordinates are the drawing's x-y (its
WCS), converted to m by ``units`` (the header's ``$INSUNITS`` unless given).
"""

from __future__ import annotations

import math
import re
import unicodedata
from collections import Counter
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from shapely.geometry import LineString, Polygon

from twin.planning.floor_map import FloorMap, MapError, MapObstacle
from twin.planning.map_reading import (
    check_keep,
    enclosed_regions,
    polygons_of,
    select_regions,
    unit_scale,
)

__all__ = [
    "DEFAULT_OBSTACLE_KEYWORDS",
    "DEFAULT_WALL_KEYWORDS",
    "INSUNITS_METRES",
    "WALL_WORDS",
    "is_wall_layer",
    "load_dxf_map",
]

DEFAULT_WALL_KEYWORDS = ("wall",)
"""Found anywhere in a layer's name (``Walls``, ``A-WALL-FULL``, ``Interior walls``)."""
WALL_WORDS = (
    # German
    "wand",
    "wände",
    "waende",
    "mauer",
    "mauern",
    # French
    "mur",
    "murs",
    "cloison",
    "cloisons",
    # Spanish
    "muro",
    "muros",
    "pared",
    "paredes",
    "tabique",
    "tabiques",
    # Italian
    "muri",
    "parete",
    "pareti",
    "tramezzo",
    "tramezzi",
)
"""Words for walls a layer's name may hold as a word of its own (split at anything that
is not a letter or a digit, ``Wände_tragend``, ``MUR-porteur``)."""
_COMPOUND_WORDS = ("wand", "wände", "waende", "mauer", "mauern")
"""German words that also end a compound (``Innenwand``, ``Außenwände``, ``Stützmauer``)."""
DEFAULT_OBSTACLE_KEYWORDS = ("obstacle", "column", "pillar", "furniture")

#: Metres per drawing unit for the DXF header's ``$INSUNITS`` codes.
INSUNITS_METRES: dict[int, float] = {
    1: 0.0254,  # inches
    2: 0.3048,  # feet
    3: 1609.344,  # miles
    4: 1e-3,  # millimetres
    5: 1e-2,  # centimetres
    6: 1.0,  # metres
    7: 1e3,  # kilometres
    8: 2.54e-8,  # microinches
    9: 2.54e-5,  # mils
    10: 0.9144,  # yards
    11: 1e-10,  # angstroms
    12: 1e-9,  # nanometres
    13: 1e-6,  # microns
    14: 0.1,  # decimetres
    15: 10.0,  # decametres
    16: 100.0,  # hectometres
}

_CURVES = {"LINE", "LWPOLYLINE", "POLYLINE", "ARC", "CIRCLE", "ELLIPSE", "SPLINE"}
_MAX_BLOCK_DEPTH = 16


def is_wall_layer(name: str) -> bool:
    """Whether a layer's name says it holds walls, by default (see the module)."""
    text = unicodedata.normalize("NFC", name).casefold()
    if any(k in text for k in DEFAULT_WALL_KEYWORDS):
        return True
    words = [w for w in re.split(r"[\W_]+", text) if w]
    return any(w in WALL_WORDS or w.endswith(_COMPOUND_WORDS) for w in words)


def _layer_matcher(layers: Iterable[str] | None, keywords: Sequence[str]) -> tuple[Any, str]:
    """A predicate on layer names and a description of it for messages."""
    if layers is None and keywords == DEFAULT_WALL_KEYWORDS:
        return is_wall_layer, (
            "layers whose name contains 'wall' or holds a German, French, Spanish or "
            "Italian word for walls (Wand, Wände, Mauer, mur, cloison, muro, pared, tabique, "
            "parete...)"
        )
    if layers is None:
        words = tuple(k.lower() for k in keywords)
        return (
            lambda name: any(w in name.lower() for w in words),
            "layers whose name contains " + " or ".join(repr(w) for w in words),
        )
    if isinstance(layers, str):
        layers = [layers]
    names = {unicodedata.normalize("NFC", str(n)).casefold() for n in layers}
    return (
        lambda name: unicodedata.normalize("NFC", name).casefold() in names
    ), "layers " + ", ".join(sorted(names))


def _entities(container: Iterable[Any], layer: str | None = None, depth: int = 0) -> Iterator:
    """Yield ``(entity, layer)`` for a layout's entities, block references exploded."""
    for entity in container:
        own = entity.dxf.get("layer", "0")
        effective = layer if (layer is not None and own == "0") else own
        if entity.dxftype() == "INSERT" and depth < _MAX_BLOCK_DEPTH:
            try:
                parts = list(entity.virtual_entities())
            except Exception:  # a broken block: counted by the caller as an INSERT
                yield entity, effective
                continue
            yield from _entities(parts, effective, depth + 1)
        else:
            yield entity, effective


def _outline(entity: Any, tolerance: float) -> tuple[np.ndarray, bool] | None:
    """The entity's outline as (n, 2) drawing-unit points in the WCS x-y plane and
    whether it is closed, or None if it has no usable outline."""
    from ezdxf import path as dxf_path

    kind = entity.dxftype()
    try:
        outline = dxf_path.make_path(entity)
        points = np.array([(v.x, v.y) for v in outline.flattening(distance=tolerance)])
    except Exception:
        return None
    if points.ndim != 2 or len(points) < 2:
        return None
    closed = False
    if kind == "CIRCLE":
        closed = True
    elif kind == "LWPOLYLINE":
        closed = bool(entity.closed)
    elif kind == "POLYLINE":
        closed = bool(entity.is_closed)
    elif kind == "SPLINE":
        closed = bool(entity.closed)
    size = float(np.ptp(points, axis=0).max())
    if size == 0.0:
        return None
    if not closed and len(points) >= 4 and np.linalg.norm(points[0] - points[-1]) <= 1e-9 * size:
        closed = True
    if closed and np.linalg.norm(points[0] - points[-1]) > 0.0:
        points = np.vstack([points, points[:1]])
    return points, closed


def load_dxf_map(
    path: str | Path,
    *,
    wall_layers: Iterable[str] | None = None,
    obstacle_layers: Iterable[str] | None = None,
    wall_thickness: float = 0.15,
    units: str | float | None = None,
    heights: dict[str, float] | None = None,
    height: float | None = None,
    keep: str = "largest",
    min_area: float = 0.05,
    arc_tolerance: float = 0.005,
) -> FloorMap:
    """Read a DXF floor plan into a :class:`FloorMap`.

    Args:
        path: the ``.dxf`` file.
        wall_layers: the layers that hold walls (names, any case); default every layer
            whose name contains ``"wall"``.
        obstacle_layers: the layers that hold obstacles; default every layer whose name
            contains ``"obstacle"``, ``"column"``, ``"pillar"`` or ``"furniture"`` (a layer
            that is both is a wall layer).
        wall_thickness: how thick a wall drawn as a single line is, m.
        units: the drawing's unit (``"mm"``, ``"cm"``, ``"m"``, ``"inch"``, ``"ft"``... or
            metres per unit); default the header's ``$INSUNITS``, metres when it is absent
            or unitless.
        heights: height above the floor by layer name (any case), m; layers not named
            stand ``math.inf`` high (to the ceiling).
        height: the ceiling's height above the floor, m; default none known (3 m
            written, :attr:`FloorMap.height_known` false).
        keep: ``"largest"`` (the largest connected piece of free floor) or ``"all"``
            (every piece of at least ``min_area``).
        min_area: pieces of free floor smaller than this are left out with
            ``keep="all"``, m^2.
        arc_tolerance: the largest distance between an arc and the chords that replace
            it, m.

    Returns:
        ``free``: the floor enclosed by the walls less walls and obstacles, drawing x-y
        in m; ``obstacles``: the walls (one per connected piece and layer) and every
        obstacle entity, named by layer, with the layer's height; ``notes``: units and
        what was passed over.

    Raises:
        MapError: a file ezdxf cannot read, a bad option, no entity on any wall layer
            (the message lists the layers found), walls that enclose no area.
    """
    try:
        import ezdxf
    except ImportError as exc:
        raise ImportError(
            f"reading a DXF floor plan needs ezdxf: pip install -e '.[maps]' ({exc})"
        ) from exc

    path = Path(path)
    check_keep(keep, path)
    if not (math.isfinite(wall_thickness) and wall_thickness > 0.0):
        raise MapError(
            path, f"wall_thickness: expected a positive width in m, got {wall_thickness}"
        )
    if not (math.isfinite(arc_tolerance) and arc_tolerance > 0.0):
        raise MapError(
            path, f"arc_tolerance: expected a positive distance in m, got {arc_tolerance}"
        )
    try:
        doc = ezdxf.readfile(path)
    except (OSError, ezdxf.DXFError, ValueError, UnicodeError, AttributeError, IndexError) as exc:
        raise MapError(path, f"not a DXF file ezdxf can read: {exc}") from None

    notes: list[str] = []
    if units is None:
        code = int(doc.header.get("$INSUNITS", 0) or 0)
        if code == 0:
            scale = 1.0
            notes.append("no $INSUNITS in the header (unitless): drawing units read as m")
        elif code in INSUNITS_METRES:
            scale = INSUNITS_METRES[code]
            notes.append(f"$INSUNITS = {code}: {scale:g} m per drawing unit")
        else:
            raise MapError(
                path,
                f"header $INSUNITS = {code} is not a length unit; expected a length unit "
                "there (4 mm, 5 cm, 6 m, 1 inch, 2 ft...) or none (read as metres)",
            )
    else:
        scale = unit_scale(units, path, "units")
        notes.append(f"units = {units!r}: {scale:g} m per drawing unit")

    is_wall, wall_rule = _layer_matcher(wall_layers, DEFAULT_WALL_KEYWORDS)
    is_obstacle, _ = _layer_matcher(obstacle_layers, DEFAULT_OBSTACLE_KEYWORDS)
    layer_heights = {str(k).lower(): float(v) for k, v in (heights or {}).items()}
    for name, value in layer_heights.items():
        if math.isnan(value) or value < 0.0:
            raise MapError(path, f"heights[{name!r}]: expected a height >= 0 m, got {value}")

    def height_of(layer: str) -> float:
        return layer_heights.get(layer.lower(), math.inf)

    tolerance = arc_tolerance / scale
    half = 0.5 * wall_thickness
    wall_lines: dict[str, list[LineString]] = {}
    obstacles: list[MapObstacle] = []
    found: Counter[str] = Counter()
    passed_over: Counter[str] = Counter()
    opened = 0
    for entity, layer in _entities(doc.modelspace()):
        found[layer] += 1
        wall = is_wall(layer)
        if not (wall or is_obstacle(layer)):
            continue
        kind = entity.dxftype()
        outline = _outline(entity, tolerance) if kind in _CURVES else None
        if outline is None:
            passed_over[f"{kind} on {layer}"] += 1
            continue
        points, closed = outline
        points = points * scale
        if wall:
            wall_lines.setdefault(layer, []).append(LineString(points))
            continue
        if closed and len(points) >= 4:
            footprint = shapely.make_valid(Polygon(points))
        else:
            opened += 1
            footprint = LineString(points).buffer(half, cap_style="flat", join_style="mitre")
        for poly in polygons_of(footprint):
            obstacles.append(MapObstacle(footprint=poly, height=height_of(layer), name=layer))

    if not wall_lines:
        listing = ", ".join(f"{name} ({n})" for name, n in sorted(found.items())) or "none"
        empty = sorted(str(layer.dxf.name) for layer in doc.layers if not found[layer.dxf.name])
        if empty:
            listing += "; layers with none: " + ", ".join(empty)
        raise MapError(
            path,
            f"no wall: no line, polyline, arc or circle on a layer read as walls; the file's "
            f"layers with entities: {listing}; expected the walls on {wall_rule}: name the "
            "layers that hold the walls with --wall-layers NAME [NAME ...]",
        )

    walls: list[MapObstacle] = []
    for layer, lines in sorted(wall_lines.items()):
        merged = shapely.line_merge(shapely.MultiLineString(lines))
        body = merged.buffer(half, cap_style="flat", join_style="mitre")
        for poly in polygons_of(body):
            walls.append(MapObstacle(footprint=poly, height=height_of(layer), name=layer))

    wall_union = shapely.union_all([w.footprint for w in walls])
    regions = enclosed_regions(wall_union)
    if not regions:
        raise MapError(
            path,
            f"the walls on layer(s) {', '.join(sorted(wall_lines))} enclose no area: expected "
            "a closed outline of walls around the floor (door gaps closed elsewhere)",
        )
    blocked = shapely.union_all([o.footprint for o in obstacles]) if obstacles else None
    pieces: list[Polygon] = []
    for region in regions:
        pieces.extend(polygons_of(region.difference(blocked) if blocked is not None else region))
    if not pieces:
        raise MapError(path, "the obstacles cover all of the floor the walls enclose")
    free, region_notes = select_regions(pieces, keep, min_area, path)
    notes.extend(region_notes)
    if opened:
        notes.append(
            f"{opened} open outline(s) on obstacle layers thickened to {wall_thickness:g} m"
        )
    if passed_over:
        listing = ", ".join(f"{n} {what}" for what, n in sorted(passed_over.items()))
        notes.append(f"entities with no outline passed over: {listing}")
    others = sorted(name for name in found if not (is_wall(name) or is_obstacle(name)))
    if others:
        notes.append(
            f"{sum(found[n] for n in others)} entities on other layers not read: "
            + ", ".join(others)
        )
    return FloorMap(
        free=free,
        obstacles=tuple(walls + obstacles),
        height=3.0 if height is None else float(height),
        source=str(path),
        notes=tuple(notes),
        height_known=height is not None,
    )
