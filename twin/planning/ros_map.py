"""A ROS occupancy grid (map_server's ``map.yaml`` and its PGM/PNG image) as a
:class:`~twin.planning.floor_map.FloorMap`.

The YAML is the one map_server, map_saver, slam_toolbox and Cartographer write::

    image: map.pgm            # relative to the YAML's folder
    resolution: 0.05          # m per pixel
    origin: [-10.0, -5.0, 0.0]  # x, y (m), yaw (rad) of the image's lower-left corner
    negate: 0
    occupied_thresh: 0.65
    free_thresh: 0.196
    mode: trinary             # optional: trinary (default), scale or raw

Each pixel becomes a cell by map_server's rule: its value ``v`` (the mean of the colour
channels, alpha aside) gives the occupancy ``p = (255 - v) / 255`` (``p = v / 255`` with
``negate``); the cell is occupied if ``p > occupied_thresh``, free if ``p < free_thresh``,
otherwise unknown (``trinary``) or of an intermediate cost (``scale``; a pixel with
alpha < 255 is unknown there). In ``raw`` mode ``v`` is the occupancy in percent
(0-100, larger values unknown, ``negate`` ignored, as map_server does) and the same
thresholds apply to ``v / 100``. Only free cells are floor: unknown and intermediate
cells are not.

Frames: the image's row 0 is the top of the map; the lower-left corner of the lower-left
pixel is at ``origin`` in the map frame, and ``yaw`` turns the grid about that corner. A
pixel (row ``r``, column ``c``) of an ``H``-row image covers the grid-frame square
``[c, c + 1] x [H - 1 - r, H - r]`` times ``resolution``. The cells are turned into
polygons exactly along their edges (no smoothing), so areas are exact multiples of the
cell's area.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import shapely
import yaml
from shapely.geometry import Polygon

from calib.io.text import NotText, read_text, yaml_load
from twin.planning.floor_map import FloorMap, MapError, MapObstacle
from twin.planning.map_reading import check_keep, select_regions

__all__ = [
    "SPECKLE_AREA",
    "OccupancyGrid",
    "clean_speckle",
    "grid_polygons",
    "load_ros_map",
    "read_occupancy_grid",
]

FREE = 0
OCCUPIED = 1
UNKNOWN = 2
INTERMEDIATE = 3
MODES = ("trinary", "scale", "raw")
SPECKLE_AREA = 0.02
"""Blobs of occupied or unknown cells smaller than this, with only free cells around them,
are read as free (``speckle=``), m^2: 8 cells at 5 cm, a blob under 15 x 15 cm. A SLAM
map's speckle is one to a few cells of sensor noise, and the robots' clearance grows each
into a disc ~1 m across that cuts corridors apart; a pillar or post (15 cm square,
0.0225 m^2, and up) is kept. Thinner things seen as a few cells (a table's or chair's
leg) are read as free too: pass a smaller area, or 0 to keep every cell as read."""


class OccupancyGrid:
    """A classified occupancy grid and where it lies in the map frame.

    Attributes:
        cells: (H, W) uint8, one of :data:`FREE`, :data:`OCCUPIED`, :data:`UNKNOWN`,
            :data:`INTERMEDIATE`; row 0 is the top of the map.
        resolution: cell size, m.
        origin: (x, y, yaw) of the lower-left corner of the lower-left cell in the map
            frame, m and rad.
        source: the YAML file.
    """

    def __init__(
        self,
        cells: np.ndarray,
        resolution: float,
        origin: tuple[float, float, float],
        source: str,
    ) -> None:
        self.cells = cells
        self.resolution = resolution
        self.origin = origin
        self.source = source

    def vertex2map(self) -> list[float]:
        """The affine map (shapely's ``[a, b, d, e, xoff, yoff]``) from grid-vertex
        coordinates (x = column, y = row, counted from the top-left corner) to the map
        frame, m."""
        height = self.cells.shape[0]
        res = self.resolution
        x0, y0, yaw = self.origin
        c, s = math.cos(yaw), math.sin(yaw)
        return [c * res, s * res, s * res, -c * res, x0 - s * height * res, y0 + c * height * res]


def _number(doc: dict, key: str, file: Path, what: str) -> float:
    value = doc[key]
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise MapError(file, f"{key!r}: expected {what}, got {value!r}")
    return float(value)


def read_occupancy_grid(path: str | Path) -> OccupancyGrid:
    """Read a map_server YAML and its image and classify every pixel.

    Args:
        path: the ``map.yaml``.

    Returns:
        The classified grid (see :class:`OccupancyGrid`).

    Raises:
        MapError: a file that is not YAML or not a mapping, a missing key (``image``,
            ``resolution``, ``origin``, ``occupied_thresh``, ``free_thresh``), a
            non-positive resolution, an origin that is not ``[x, y, yaw]``, thresholds
            outside [0, 1] or ``free_thresh >= occupied_thresh``, an unknown ``mode``, an
            image that is missing or unreadable.
    """
    path = Path(path)
    try:
        text = read_text(path)
    except OSError as exc:
        raise MapError(path, f"cannot read the map YAML: {exc.strerror or exc}") from None
    except NotText as exc:
        raise MapError(path, f"cannot read the map YAML: {exc}") from None
    try:
        doc = yaml_load(text)
    except yaml.YAMLError as exc:
        raise MapError(path, f"not valid YAML: {exc}") from None
    if not isinstance(doc, dict):
        raise MapError(path, f"expected a mapping of map_server keys, got {type(doc).__name__}")
    required = ("image", "resolution", "origin", "occupied_thresh", "free_thresh")
    missing = [key for key in required if key not in doc]
    if missing:
        raise MapError(
            path,
            f"missing key(s) {', '.join(missing)}: a map_server YAML needs "
            f"{', '.join(required)} (negate and mode are optional)",
        )

    resolution = _number(doc, "resolution", path, "a positive number of m per pixel")
    if resolution <= 0.0:
        raise MapError(path, f"'resolution': expected a positive m per pixel, got {resolution}")

    origin = doc["origin"]
    if (
        not isinstance(origin, list | tuple)
        or len(origin) not in (2, 3)
        or not all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
            for v in origin
        )
    ):
        raise MapError(path, f"'origin': expected [x, y, yaw] (m, m, rad), got {origin!r}")
    x0, y0 = float(origin[0]), float(origin[1])
    yaw = float(origin[2]) if len(origin) == 3 else 0.0

    occupied = _number(doc, "occupied_thresh", path, "a number in [0, 1]")
    free = _number(doc, "free_thresh", path, "a number in [0, 1]")
    for key, value in (("occupied_thresh", occupied), ("free_thresh", free)):
        if not 0.0 <= value <= 1.0:
            raise MapError(path, f"{key!r}: expected a number in [0, 1], got {value}")
    if free >= occupied:
        raise MapError(
            path,
            f"'free_thresh' ({free}) must be below 'occupied_thresh' ({occupied})",
        )

    negate = doc.get("negate", 0)
    if negate not in (0, 1, True, False):
        raise MapError(path, f"'negate': expected 0 or 1, got {negate!r}")
    mode = str(doc.get("mode", "trinary")).strip().lower()
    if mode not in MODES:
        raise MapError(path, f"'mode': expected one of {', '.join(MODES)}, got {mode!r}")

    image_name = doc["image"]
    if not isinstance(image_name, str) or not image_name.strip():
        raise MapError(path, f"'image': expected the image's file name, got {image_name!r}")
    image_path = Path(image_name)
    if not image_path.is_absolute():
        image_path = path.parent / image_path
    if not image_path.is_file():
        raise MapError(path, f"'image': {image_path} does not exist")
    try:
        raw = np.fromfile(image_path, dtype=np.uint8)
        image = cv2.imdecode(raw, cv2.IMREAD_UNCHANGED) if raw.size else None
    except (OSError, cv2.error):
        image = None
    if image is None or image.size == 0:
        raise MapError(path, f"'image': {image_path} is not an image OpenCV can read")

    cells = _classify(image, occupied, free, bool(negate), mode)
    return OccupancyGrid(cells, resolution, (x0, y0, yaw), str(path))


def _classify(
    image: np.ndarray, occupied: float, free: float, negate: bool, mode: str
) -> np.ndarray:
    """Classify pixels by map_server's rule (see the module's docstring).

    Args:
        image: (H, W) or (H, W, C) uint8/uint16 as OpenCV reads it (BGR[A]).

    Returns:
        (H, W) uint8 of FREE, OCCUPIED, UNKNOWN, INTERMEDIATE.
    """
    alpha = None
    pixels = image.astype(np.float64)
    if image.dtype == np.uint16:
        pixels *= 255.0 / 65535.0
    if pixels.ndim == 3:
        if pixels.shape[2] in (2, 4):
            alpha = pixels[..., -1]
            pixels = pixels[..., :-1]
        value = pixels.mean(axis=2)
    else:
        value = pixels
    cells = np.full(value.shape, UNKNOWN, dtype=np.uint8)
    if mode == "raw":
        value = np.rint(value)
        known = value <= 100.0
        p = value / 100.0
        cells[known & (p > occupied)] = OCCUPIED
        cells[known & (p < free)] = FREE
        cells[known & (p >= free) & (p <= occupied)] = INTERMEDIATE
        return cells
    if negate:
        value = 255.0 - value
    p = (255.0 - value) / 255.0
    cells[p > occupied] = OCCUPIED
    cells[p < free] = FREE
    if mode == "scale":
        between = (p >= free) & (p <= occupied)
        if alpha is not None:
            between &= alpha >= 255.0
        cells[between] = INTERMEDIATE
    return cells


def clean_speckle(cells: np.ndarray, most: int) -> tuple[np.ndarray, int, int, int]:
    """Read as free the blobs of fewer than ``most`` cells that are not free (occupied,
    unknown or intermediate) and that free cells surround.

    Blobs are 8-connected (cells that touch at a corner are one blob: a wall drawn as a
    diagonal line of cells stays one wall, and a speck touching a wall at a corner is part
    of it); a blob that touches the image's edge is kept whatever its size. A SLAM map's
    speckle is both: cells read occupied by sensor noise, and cells no ray ended in or
    crossed (unknown) amid the seen floor.

    Args:
        cells: (H, W) uint8 of FREE, OCCUPIED, UNKNOWN, INTERMEDIATE.
        most: blobs of fewer cells than this are removed (0 or 1: none).

    Returns:
        ``(cleaned, blobs, occupied, other)``: ``cells`` with the blobs FREE (a copy when
        any is), how many blobs were removed, and how many of their cells were occupied and
        how many unknown or intermediate.
    """
    blocked = cells != FREE
    if most <= 1 or not blocked.any():
        return cells, 0, 0, 0
    _, labels, stats, _ = cv2.connectedComponentsWithStats(blocked.astype(np.uint8), connectivity=8)
    small = stats[:, cv2.CC_STAT_AREA] < most
    edge = np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]])
    small[edge] = False
    small[0] = False  # the free cells
    remove = small[labels] & blocked
    if not remove.any():
        return cells, 0, 0, 0
    occupied = int(np.count_nonzero(remove & (cells == OCCUPIED)))
    out = cells.copy()
    out[remove] = FREE
    return out, int(small.sum()), occupied, int(remove.sum()) - occupied


def grid_polygons(mask: np.ndarray) -> list[Polygon]:
    """The connected regions of a boolean grid as polygons traced along the cells' edges.

    Cells that touch only at a corner belong to different regions. Holes (cells not in
    ``mask`` enclosed by cells that are) are the polygons' interiors.

    Args:
        mask: (H, W) bool, row 0 at the top.

    Returns:
        The regions in grid-vertex coordinates: x = column, y = row, both counted from the
        top-left corner of the top-left cell (so a cell ``(r, c)`` is the unit square
        ``[c, c + 1] x [r, r + 1]``).
    """
    mask = np.asarray(mask, dtype=bool)
    if not mask.any():
        return []
    rows, cols = mask.shape
    padded = np.pad(mask, 1)
    # Boundary edges: horizontal ones run along vertex row i from vertex column j to j + 1,
    # vertical ones along vertex column j from vertex row i to i + 1.
    h_edge = padded[1:, 1:-1] != padded[:-1, 1:-1]  # (rows + 1, cols)
    v_edge = padded[1:-1, 1:] != padded[1:-1, :-1]  # (rows, cols + 1)
    # Vertices a perpendicular edge touches: straight runs must be split there so that the
    # lines are noded where they meet (only where four boundary edges meet).
    v_touch = np.zeros((rows + 1, cols + 1), dtype=bool)
    v_touch[:-1] |= v_edge
    v_touch[1:] |= v_edge
    h_touch = np.zeros((rows + 1, cols + 1), dtype=bool)
    h_touch[:, :-1] |= h_edge
    h_touch[:, 1:] |= h_edge

    segments = [_runs(h_edge, v_touch), _runs(v_edge.T, h_touch.T)[:, :, ::-1]]
    coords = np.concatenate(segments).astype(np.float64)
    lines = shapely.linestrings(coords)
    faces = np.asarray(shapely.get_parts(shapely.polygonize(lines)))
    if faces.size == 0:
        return []
    inside = shapely.get_coordinates(shapely.point_on_surface(faces))
    col = np.clip(np.floor(inside[:, 0]).astype(int), 0, cols - 1)
    row = np.clip(np.floor(inside[:, 1]).astype(int), 0, rows - 1)
    return list(faces[mask[row, col]])


def _runs(edges: np.ndarray, touch: np.ndarray) -> np.ndarray:
    """Maximal straight runs of boundary edges along each row of ``edges``, split at
    vertices ``touch`` marks.

    Args:
        edges: (R, N) bool, edge ``[i, j]`` from vertex ``(i, j)`` to ``(i, j + 1)``.
        touch: (R, N + 1) bool.

    Returns:
        (n, 2, 2) int segments ``[[j0, i], [j1, i]]`` (x = along the row, y = row).
    """
    before = np.zeros_like(edges)
    before[:, 1:] = edges[:, :-1]
    after = np.zeros_like(edges)
    after[:, :-1] = edges[:, 1:]
    starts = edges & (~before | touch[:, :-1])
    ends = edges & (~after | touch[:, 1:])
    si, sj = np.nonzero(starts)
    ei, ej = np.nonzero(ends)
    out = np.empty((si.size, 2, 2), dtype=np.int64)
    out[:, 0, 0] = sj
    out[:, 0, 1] = si
    out[:, 1, 0] = ej + 1
    out[:, 1, 1] = ei
    return out


def load_ros_map(
    path: str | Path,
    *,
    min_area: float = 0.05,
    keep: str = "all",
    height: float | None = None,
    speckle: float = SPECKLE_AREA,
) -> FloorMap:
    """Read a ROS occupancy grid (map_server YAML + PGM/PNG) into a :class:`FloorMap`.

    Args:
        path: the ``map.yaml``.
        min_area: regions of free floor smaller than this are left out (counted in the
            notes), m^2.
        keep: ``"all"`` (the largest region and every other of at least ``min_area``) or
            ``"largest"`` (only the largest connected region).
        height: the ceiling's height above the floor, m; default none known (a grid has
            none: 3 m written, :attr:`FloorMap.height_known` false).
        speckle: blobs of occupied or unknown cells smaller than this with only free
            cells around them are read as free (:func:`clean_speckle`; counted in the
            notes), m^2; 0 keeps every cell as read. Default :data:`SPECKLE_AREA`.

    Returns:
        ``free``: the union of the free cells in the map frame (a Polygon, or a
        MultiPolygon of the regions, largest first); ``obstacles``: one
        :class:`MapObstacle` per connected region of occupied cells (name
        ``"occupied"``, height ``math.inf``); ``notes``: the cell counts and what was left
        out.

    Raises:
        MapError: see :func:`read_occupancy_grid`, a map with no free cell, and a
            ``speckle`` that is not a finite number of m^2 at least 0.
    """
    path = Path(path)
    check_keep(keep, path)
    if (
        isinstance(speckle, bool)
        or not isinstance(speckle, int | float)
        or not math.isfinite(speckle)
        or speckle < 0.0
    ):
        raise MapError(
            path,
            f"speckle: expected an area of at least 0 m^2 (0: keep every cell), got {speckle!r}",
        )
    grid = read_occupancy_grid(path)
    counts = np.bincount(grid.cells.ravel(), minlength=4)
    most = math.ceil(speckle / grid.resolution**2 - 1e-9)
    grid.cells, blobs, occupied_specks, other_specks = clean_speckle(grid.cells, most)
    if counts[FREE] == 0:
        raise MapError(
            path,
            "the image has no free cell (no pixel whose occupancy is below free_thresh): "
            "an empty map",
        )
    matrix = grid.vertex2map()
    free_cells = shapely.transform(
        np.asarray(grid_polygons(grid.cells == FREE), dtype=object),
        lambda xy: _affine(xy, matrix),
    )
    occupied_cells = shapely.transform(
        np.asarray(grid_polygons(grid.cells == OCCUPIED), dtype=object),
        lambda xy: _affine(xy, matrix),
    )
    free, notes = select_regions(list(free_cells), keep, min_area, path)
    cell_notes = (
        f"{grid.cells.shape[1]} x {grid.cells.shape[0]} cells of {grid.resolution:g} m: "
        f"{counts[FREE]} free, {counts[OCCUPIED]} occupied, {counts[UNKNOWN]} unknown"
        + (f", {counts[INTERMEDIATE]} of intermediate occupancy" if counts[INTERMEDIATE] else ""),
    )
    if blobs:
        cell_notes += (
            f"{blobs} speck(s) under speckle = {speckle:g} m^2 amid free cells read as free: "
            f"{occupied_specks} occupied and {other_specks} unknown cells",
        )
    obstacles = tuple(
        MapObstacle(footprint=poly, height=math.inf, name="occupied")
        for poly in sorted(occupied_cells, key=lambda p: p.area, reverse=True)
    )
    return FloorMap(
        free=free,
        obstacles=obstacles,
        height=3.0 if height is None else float(height),
        source=str(path),
        notes=cell_notes + notes,
        height_known=height is not None,
    )


def _affine(xy: np.ndarray, matrix: list[float]) -> np.ndarray:
    a, b, d, e, xoff, yoff = matrix
    out = np.empty_like(xy)
    out[:, 0] = a * xy[:, 0] + b * xy[:, 1] + xoff
    out[:, 1] = d * xy[:, 0] + e * xy[:, 1] + yoff
    return out
