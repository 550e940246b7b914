"""A building mesh (OBJ, STL, PLY, glTF/GLB, read with trimesh) as a
:class:`~twin.planning.floor_map.FloorMap`.

The floor plan is the mesh's horizontal section at ``floor_z + section_height`` (the band
the robots drive in): the section's line segments split the plane into faces, and a face
is solid (inside a wall, a pillar, a box) when a vertical ray from it upwards first leaves
the mesh through an upward-facing triangle (the top of what it stands in), and air
otherwise (it meets a ceiling's underside, or nothing). This needs the triangles' normals
to point outwards, as CAD and modelling tools write them; bodies may overlap or touch.

The free floor is the largest region the solid section encloses (the room inside the
outer walls) minus every solid face inside it. Each connected piece of the solid section
is a :class:`~twin.planning.floor_map.MapObstacle` whose height is the highest point at
which vertical rays from inside it first leave the mesh (the top of the wall, the box,
the pillar), above the floor.

Frames: the mesh's own x-y (``up="z"``), or for y-up models (glTF's convention,
``up="y"``) x and -z (a turn of +90 deg about x that takes y to z); heights above
``floor_z``; all in m after ``units``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import shapely
from shapely.geometry import Polygon

from twin.planning.floor_map import FloorMap, MapError, MapObstacle
from twin.planning.map_reading import (
    check_keep,
    enclosed_regions,
    polygons_of,
    select_regions,
    unit_scale,
)

__all__ = ["FLOOR_SLAB", "floor_height", "load_mesh_map", "rays_up"]

#: How far above the mesh's lowest point the top of a floor slab may be, m.
FLOOR_SLAB = 0.5
#: The grid the section's vertices are snapped to before they are joined, m.
SNAP = 1e-6
_PAIRS_PER_CHUNK = 4_000_000


def _load(path: Path, units: str | float, up: str) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3) in m, z up, and faces (m, 3) of the file's triangles."""
    import trimesh

    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many kinds for bad files
        raise MapError(path, f"not a mesh trimesh can read: {exc}") from None
    if not isinstance(mesh, trimesh.Trimesh):
        raise MapError(path, f"expected a triangle mesh, got a {type(mesh).__name__}")
    vertices = np.asarray(mesh.vertices, dtype=np.float64) * unit_scale(units, path, "units")
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if len(faces) == 0 or len(vertices) == 0:
        raise MapError(path, "the mesh is empty (no triangle)")
    if not np.isfinite(vertices).all():
        raise MapError(path, "the mesh has vertices that are not finite numbers")
    if up == "y":
        vertices = np.column_stack([vertices[:, 0], -vertices[:, 2], vertices[:, 1]])
    return vertices, faces


def floor_height(triangles: np.ndarray) -> float:
    """The floor's z: the mesh's lowest z, or, if upward-facing horizontal triangles lie
    within :data:`FLOOR_SLAB` of it (the top of a floor slab), the z of the largest
    upward-facing area there.

    Args:
        triangles: (T, 3, 3) vertices, m, z up.
    """
    lowest = float(triangles[:, :, 2].min())
    normal = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    area2 = np.linalg.norm(normal, axis=1)
    flat = (normal[:, 2] > 0.999 * area2) & (area2 > 0.0)
    z = triangles[:, :, 2].mean(axis=1)
    candidates = flat & (z <= lowest + FLOOR_SLAB)
    if not candidates.any():
        return lowest
    levels = np.round(z[candidates] / SNAP).astype(np.int64)
    unique, inverse = np.unique(levels, return_inverse=True)
    area = np.bincount(inverse, weights=area2[candidates])
    return float(unique[np.argmax(area)] * SNAP)


def rays_up(triangles: np.ndarray, points: np.ndarray, z0: float) -> tuple[np.ndarray, np.ndarray]:
    """Cast vertical rays upwards from ``(x, y, z0)`` and report the first triangle hit.

    Args:
        triangles: (T, 3, 3) vertices, m, z up, wound so that normals point outwards.
        points: (P, 2) x, y of the rays, m.
        z0: the rays' start height, m.

    Returns:
        ``(z, leaving)``: (P,) the height of the first hit (``inf`` where none) and
        (P,) bool, whether a triangle hit there faces up (the ray leaves a solid).
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    z_hit = np.full(len(points), np.inf)
    leaving = np.zeros(len(points), dtype=bool)
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    e1, e2 = b - a, c - a
    den = e1[:, 0] * e2[:, 1] - e2[:, 0] * e1[:, 1]
    keep = (np.abs(den) > 1e-12) & (triangles[:, :, 2].max(axis=1) > z0)
    if not keep.any() or len(points) == 0:
        return z_hit, leaving
    a, e1, e2, den = a[keep], e1[keep], e2[keep], den[keep]
    lo = triangles[keep, :, :2].min(axis=1) - 1e-9
    hi = triangles[keep, :, :2].max(axis=1) + 1e-9
    chunk = max(1, _PAIRS_PER_CHUNK // len(a))
    for start in range(0, len(points), chunk):
        block = points[start : start + chunk]
        inside_box = (
            (block[:, None, 0] >= lo[None, :, 0])
            & (block[:, None, 0] <= hi[None, :, 0])
            & (block[:, None, 1] >= lo[None, :, 1])
            & (block[:, None, 1] <= hi[None, :, 1])
        )
        pi, ti = np.nonzero(inside_box)
        if pi.size == 0:
            continue
        d = block[pi] - a[ti, :2]
        u = (d[:, 0] * e2[ti, 1] - e2[ti, 0] * d[:, 1]) / den[ti]
        v = (e1[ti, 0] * d[:, 1] - d[:, 0] * e1[ti, 1]) / den[ti]
        eps = 1e-9
        hit = (u >= -eps) & (v >= -eps) & (u + v <= 1.0 + eps)
        z = a[ti, 2] + u * e1[ti, 2] + v * e2[ti, 2]
        hit &= z > z0 + 1e-9
        pi, ti, z = pi[hit], ti[hit], z[hit]
        if pi.size == 0:
            continue
        first = np.full(len(block), np.inf)
        np.minimum.at(first, pi, z)
        faces_up = den[ti] > 0.0  # counter-clockwise seen from above: normal up
        at_first = z <= first[pi] + 1e-6
        up = np.zeros(len(block), dtype=bool)
        np.logical_or.at(up, pi[at_first], faces_up[at_first])
        z_hit[start : start + len(block)] = first
        leaving[start : start + len(block)] = up
    return z_hit, leaving


def _samples(poly: Polygon, count: int = 16) -> np.ndarray:
    """(n, 2) points inside a polygon: one on its surface and some just inside its
    outline, m."""
    points = [shapely.get_coordinates(poly.point_on_surface())]
    size = math.sqrt(poly.area)
    inner = poly.buffer(-min(1e-3, 0.05 * size), join_style="mitre")
    for part in polygons_of(inner):
        ring = np.asarray(part.exterior.coords)[:-1]
        step = max(1, len(ring) // count)
        points.append(ring[::step])
    return np.concatenate(points)


def load_mesh_map(
    path: str | Path,
    *,
    section_height: float = 0.3,
    floor_z: float | None = None,
    up: str = "z",
    units: str | float = 1.0,
    keep: str = "largest",
    min_area: float = 0.05,
) -> FloorMap:
    """Read a building mesh into a :class:`FloorMap` by cutting it at the robots' height.

    Args:
        path: an ``.obj``, ``.stl``, ``.ply``, ``.gltf`` or ``.glb`` file.
        section_height: where the plan is cut, above the floor, m (the robots' height
            band).
        floor_z: the floor's height in the mesh's frame (after ``units``), m; default the
            top of a floor slab within :data:`FLOOR_SLAB` of the lowest point, or the
            lowest point (see :func:`floor_height`).
        up: the mesh's up axis, ``"z"`` or ``"y"`` (glTF's convention).
        units: the mesh's unit (``"mm"``, ``"m"``... or metres per unit).
        keep: ``"largest"`` (the largest region of free floor) or ``"all"`` (every
            enclosed region of at least ``min_area``).
        min_area: regions smaller than this are left out with ``keep="all"``, m^2.

    Returns:
        ``free``: the floor enclosed by the section, mesh x-y in m; ``obstacles``: each
        connected piece of the solid section (name ``"section"``) with its height above
        the floor (``inf`` where a ray never leaves the mesh); ``height``: the mesh's top
        above the floor; ``notes``: the floor and cut heights.

    Raises:
        MapError: a file trimesh cannot read, an empty mesh, bad options, a section that
            is empty at the cut height (the message says which), a section that encloses
            no floor.
    """
    path = Path(path)
    check_keep(keep, path)
    if up not in ("z", "y"):
        raise MapError(path, f"up: expected 'z' or 'y', got {up!r}")
    if not (math.isfinite(section_height) and section_height > 0.0):
        raise MapError(
            path, f"section_height: expected a positive height in m, got {section_height}"
        )
    vertices, faces = _load(path, units, up)
    triangles = vertices[faces]
    if floor_z is None:
        floor = floor_height(triangles)
    else:
        floor = float(floor_z)
        if not math.isfinite(floor):
            raise MapError(path, f"floor_z: expected a height in m, got {floor_z}")
    cut = floor + section_height
    top = float(triangles[:, :, 2].max())
    where = f"at z = {cut:.4g} m ({section_height:g} m above the floor at z = {floor:.4g} m)"

    segments = _section(triangles, cut)
    if len(segments) == 0:
        raise MapError(
            path,
            f"the section {where} is empty: the mesh spans z = "
            f"{triangles[:, :, 2].min():.4g} to {top:.4g} m",
        )
    lines = shapely.linestrings(segments)
    noded = shapely.union_all(lines, grid_size=SNAP)
    faces_2d = np.asarray(shapely.get_parts(shapely.polygonize(shapely.get_parts(noded))))
    if faces_2d.size == 0:
        raise MapError(path, f"the section {where} has no closed outline")
    inside = shapely.get_coordinates(shapely.point_on_surface(faces_2d))
    _, leaving = rays_up(triangles, inside, cut)
    solid = shapely.union_all(faces_2d[leaving]) if leaving.any() else None
    regions = enclosed_regions(solid) if solid is not None else []
    if not regions:
        raise MapError(
            path,
            f"the section {where} encloses no floor: expected walls (closed bodies with "
            "outward normals) around it",
        )
    free, notes = select_regions(regions, keep, min_area, path)

    obstacles = []
    for poly in sorted(polygons_of(solid), key=lambda p: p.area, reverse=True):
        z, _ = rays_up(triangles, _samples(poly), cut)
        obstacles.append(MapObstacle(footprint=poly, height=float(z.max()) - floor, name="section"))
    return FloorMap(
        free=free,
        obstacles=tuple(obstacles),
        height=top - floor,
        height_known=True,
        source=str(path),
        notes=(
            f"floor at z = {floor:.4g} m"
            + (" (given)" if floor_z is not None else " (found)")
            + f", plan cut {where}",
            *notes,
        ),
    )


def _section(triangles: np.ndarray, z: float) -> np.ndarray:
    """(n, 2, 2) x-y segments where the plane at height ``z`` crosses the triangles, m.

    Triangles lying in the plane and crossings that touch it only at a vertex give no
    segment."""
    dz = triangles[:, :, 2] - z
    above = dz > 0.0
    count = above.sum(axis=1)
    crossing = (count == 1) | (count == 2)
    tri, dz, above = triangles[crossing], dz[crossing], above[crossing]
    # The lone vertex (the one on its own side) and the two edges from it.
    lone_up = above.sum(axis=1) == 1
    lone = np.where(lone_up, np.argmax(above, axis=1), np.argmin(above, axis=1))
    rows = np.arange(len(tri))
    i0, i1, i2 = lone, (lone + 1) % 3, (lone + 2) % 3
    out = np.empty((len(tri), 2, 2))
    for k, other in enumerate((i1, i2)):
        p, q = tri[rows, i0], tri[rows, other]
        dp, dq = dz[rows, i0], dz[rows, other]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(dp != dq, dp / (dp - dq), 0.0)
        out[:, k] = p[:, :2] + t[:, None] * (q[:, :2] - p[:, :2])
    length = np.linalg.norm(out[:, 1] - out[:, 0], axis=1)
    return out[length > 0.0]
