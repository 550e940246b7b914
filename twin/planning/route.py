"""Shortest routes over a site's floor with the robots' clearance taken off, as pure
functions over shapely geometry (map frame, m).

A robot's centre may be anywhere in ``reachable`` (for example
:meth:`twin.planning.floor_map.FloorMap.reachable`, the free floor shrunk by the robot's
clearance). The shortest path between two points of a polygonal region is a polyline that
bends only at the region's reflex vertices (the corners that point into the free floor:
convex corners of the obstacles, concave corners of the walls), so it is found on a
visibility graph: its nodes are those vertices plus the start and the goal, its edges the
segments that stay inside the region, weighted by their lengths (Lozano-Pérez and Wesley,
1979). Two filters keep the graph small:

- an edge between two corners is kept only where it is tangent at both (the corner's two
  boundary edges lie on one side of it): a shortest path never bends at a corner it does
  not wrap around;
- whether a segment stays inside is asked of a prepared (indexed) copy of the region grown
  by 1e-9 m, all segments of a batch at once (``shapely.covers`` over an array), and only
  within the connected piece of the floor that holds both ends.

Measured on one CPU core of a 2-core machine, on ``_benchmark_site`` below (a 60 x 15 m
hall with 60 round pillars and 6 rectangular structures, 0.35 m clearance):

- shrunk with ``quad_segs=2``: 2,042 vertices, 1,970 reflex corners, 6,560 edges; building
  the exact graph (``simplify=0``) takes 0.36 s, the default (``simplify=0.02``: 1,008
  corners) 0.13 s; a query (:meth:`RouteGraph.path`) about 4 ms;
- shrunk with shapely's default ``quad_segs=16`` (what ``FloorMap.reachable`` gives):
  5,236 vertices; exact build 1.4 s, default build 0.14 s; a query about 5 ms. The
  simplified graph's paths were 0.4 % longer on average.
"""

from __future__ import annotations

import math
from typing import Final

import networkx as nx
import numpy as np
import shapely
from numpy.typing import ArrayLike, NDArray
from shapely.geometry import GeometryCollection, LineString, MultiPolygon, Point, Polygon
from shapely.geometry.base import BaseGeometry
from shapely.geometry.polygon import orient

__all__ = ["NoPathError", "RouteGraph", "corridor_width", "shortest_path"]

#: How far the region is grown before asking whether a segment stays inside it, m: a
#: segment that runs along a wall or ends on a corner counts as inside.
TOLERANCE: Final[float] = 1e-9

# |sin| of an angle below which two directions count as parallel.
_PARALLEL: Final[float] = 1e-9

# How many candidate segments are tested in one vectorised call.
_CHUNK: Final[int] = 200_000

_START: Final[int] = -1
_GOAL: Final[int] = -2


class NoPathError(ValueError):
    """No path joins two points: one of them is outside the reachable floor, or they lie in
    separate regions of it (a door narrower than twice the clearance, a closed room).

    Attributes:
        start: the start point (x, y), m.
        goal: the goal point (x, y), m.
        reason: why there is no path.
    """

    def __init__(self, start: ArrayLike, goal: ArrayLike, reason: str) -> None:
        self.start = tuple(float(v) for v in np.asarray(start, dtype=float).ravel())
        self.goal = tuple(float(v) for v in np.asarray(goal, dtype=float).ravel())
        self.reason = reason
        super().__init__(
            f"no path from start {_fmt(self.start)} to goal {_fmt(self.goal)}: {reason}"
        )


def _fmt(point: ArrayLike) -> str:
    return "(" + ", ".join(f"{float(v):.3f}" for v in np.asarray(point).ravel()) + ")"


def _as_point(value: ArrayLike, name: str) -> NDArray[np.float64]:
    point = np.asarray(value, dtype=float)
    if point.shape != (2,) or not np.all(np.isfinite(point)):
        raise ValueError(f"{name} must be a finite point (x, y) in m, got {value!r}")
    return point


def _polygons(geometry: BaseGeometry, name: str = "reachable") -> list[Polygon]:
    """The non-empty polygons of a Polygon, MultiPolygon or GeometryCollection."""
    if isinstance(geometry, Polygon):
        return [] if geometry.is_empty else [geometry]
    if isinstance(geometry, MultiPolygon | GeometryCollection):
        out: list[Polygon] = []
        for part in geometry.geoms:
            if isinstance(part, Polygon | MultiPolygon | GeometryCollection):
                out.extend(_polygons(part, name))
            elif not part.is_empty:
                raise ValueError(
                    f"{name} must be polygonal (Polygon or MultiPolygon), it holds a "
                    f"{part.geom_type}"
                )
        return out
    raise ValueError(
        f"{name} must be polygonal (Polygon or MultiPolygon), got {geometry.geom_type}"
    )


def _grow(polygon: Polygon) -> Polygon:
    """``polygon`` grown by :data:`TOLERANCE` with mitred corners (no new vertices),
    prepared for many predicate calls."""
    grown = shapely.buffer(polygon, TOLERANCE, join_style="mitre")
    shapely.prepare(grown)
    return grown


def _cross(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _unit(v: NDArray[np.float64]) -> NDArray[np.float64]:
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(norm > 0.0, norm, 1.0)


def _reflex_corners(
    polygon: Polygon,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The reflex vertices of ``polygon`` (the free region turns right there when walked
    with the region on the left) and, for each, the unit directions to its two neighbours
    on the ring: arrays of shape (M, 2)."""
    points, to_prev, to_next = [], [], []
    polygon = orient(polygon, sign=1.0)  # exterior counter-clockwise, holes clockwise
    for ring in (polygon.exterior, *polygon.interiors):
        xy = np.asarray(ring.coords, dtype=float)[:-1]
        if len(xy) >= 2:
            keep = np.any(xy != np.roll(xy, 1, axis=0), axis=1)  # drop repeated points
            xy = xy[keep]
        if len(xy) < 3:
            continue
        prev = _unit(np.roll(xy, 1, axis=0) - xy)
        nxt = _unit(np.roll(xy, -1, axis=0) - xy)
        # walking prev -> xy -> next: turn = cross(xy - prev, next - xy) = cross(-prev, nxt)
        reflex = _cross(-prev, nxt) < -_PARALLEL
        points.append(xy[reflex])
        to_prev.append(prev[reflex])
        to_next.append(nxt[reflex])
    if not points:
        empty = np.zeros((0, 2))
        return empty, empty, empty
    return np.concatenate(points), np.concatenate(to_prev), np.concatenate(to_next)


def _tangent(
    d: NDArray[np.float64], to_prev: NDArray[np.float64], to_next: NDArray[np.float64]
) -> NDArray[np.bool_]:
    """Whether lines along the directions ``d`` through corners leave both of the corner's
    boundary edges (unit directions ``to_prev``, ``to_next``) on one side, touching the
    corner without entering it: shapes (..., 2) broadcast -> (...)."""
    side = _cross(d, to_prev) * _cross(d, to_next)
    return side >= -_PARALLEL * np.sum(d * d, axis=-1)


class RouteGraph:
    """The visibility graph of a reachable floor, built once per site and clearance for many
    shortest-path queries.

    Args:
        reachable: where a robot's centre may be, map frame, m (Polygon or MultiPolygon;
            pieces that are not connected are separate regions).
        simplify: tolerance, m. With 0 the corners are every reflex vertex of
            ``reachable`` (the exact visibility graph). Above 0 they are the reflex
            vertices of ``reachable`` shrunk by ``simplify`` and then simplified by it
            (Douglas-Peucker, topology kept): that polygon lies inside ``reachable``, so the
            segments tangent to it do not cut the arcs and jagged walls it smooths, and it
            has far fewer corners. Every edge is still checked against ``reachable``
            itself, so paths never leave it; they may be a few cm longer than the exact
            shortest one, and a gap narrower than ``2 * simplify`` is not used. A start or
            goal closer than ``2 * simplify`` to the floor's edge may not see the shrunk
            corners that would lead to it (at the back of a pocket, say) and the path then
            goes round: the default is the exact graph.

    Attributes:
        points: the graph's corners, (N, 2), m.
        graph: the networkx graph over the corner indices 0..N-1 (edge attribute
            ``weight``: length, m).

    A query adds the start and the goal to ``graph`` for its duration: an instance is not
    safe to query from several threads at once.
    """

    def __init__(self, reachable: BaseGeometry, *, simplify: float = 0.0) -> None:
        if not math.isfinite(simplify) or simplify < 0.0:
            raise ValueError(f"simplify must be a finite tolerance >= 0 m, got {simplify!r}")
        self.reachable = reachable
        self.simplify = float(simplify)
        pieces = _polygons(reachable)
        self._regions = [_grow(piece) for piece in pieces]
        self._tree = shapely.STRtree(self._regions)

        points, to_prev, to_next, region = [], [], [], []
        for index, piece in enumerate(pieces):
            for part in self._corner_source(piece):
                pts, prev, nxt = _reflex_corners(part)
                points.append(pts)
                to_prev.append(prev)
                to_next.append(nxt)
                region.append(np.full(len(pts), index))
        if points:
            self.points = np.concatenate(points)
            self._to_prev = np.concatenate(to_prev)
            self._to_next = np.concatenate(to_next)
            self._region_of = np.concatenate(region)
        else:
            self.points = np.zeros((0, 2))
            self._to_prev = self._to_next = np.zeros((0, 2))
            self._region_of = np.zeros(0, dtype=int)

        self.graph = nx.Graph()
        self.graph.add_nodes_from(range(len(self.points)))
        for index in range(len(pieces)):
            members = np.flatnonzero(self._region_of == index)
            self.graph.add_weighted_edges_from(self._corner_edges(index, members))

    def _corner_source(self, piece: Polygon) -> list[Polygon]:
        """The polygons whose reflex corners become the graph's nodes for one region: the
        region itself, or (``simplify > 0``) the region shrunk by ``simplify`` and then
        simplified by it, which lies inside the region (so its chords do not cut the
        region's corners) and has few corners where the region has arcs or jagged walls."""
        if self.simplify == 0.0:
            return [piece]
        shrunk = shapely.buffer(piece, -self.simplify, join_style="mitre")
        return _polygons(shrunk.simplify(self.simplify, preserve_topology=True))

    def _corner_edges(self, region: int, members: NDArray[np.intp]) -> list[tuple[int, int, float]]:
        """The visible, doubly tangent edges between the corners ``members`` of one region."""
        edges: list[tuple[int, int, float]] = []
        xy = self.points[members]
        prev, nxt = self._to_prev[members], self._to_next[members]
        m = len(members)
        block = max(1, _CHUNK // max(m, 1))
        for lo in range(0, m - 1, block):
            rows = np.arange(lo, min(lo + block, m - 1))
            # every pair (i, j) with i in rows and j > i, as (len(rows), m - lo - 1) arrays
            cols = np.arange(lo + 1, m)
            d = xy[None, cols] - xy[rows, None]
            keep = (cols[None, :] > rows[:, None]) & _tangent(d, prev[rows, None], nxt[rows, None])
            keep &= _tangent(d, prev[None, cols], nxt[None, cols])
            a, b = np.nonzero(keep)
            i, j = rows[a], cols[b]
            visible = self._visible(region, xy[i], xy[j])
            i, j = i[visible], j[visible]
            lengths = np.linalg.norm(xy[j] - xy[i], axis=1)
            edges.extend(
                zip(members[i].tolist(), members[j].tolist(), lengths.tolist(), strict=True)
            )
        return edges

    def _visible(
        self, region: int, a: NDArray[np.float64], b: NDArray[np.float64]
    ) -> NDArray[np.bool_]:
        """Whether each segment a[k]-b[k] stays inside the region (grown by the tolerance)."""
        if len(a) == 0:
            return np.zeros(0, dtype=bool)
        lines = shapely.linestrings(np.stack([a, b], axis=1))
        return np.asarray(shapely.covers(self._regions[region], lines), dtype=bool)

    def region_of(self, point: ArrayLike) -> int | None:
        """The index of the connected region of the reachable floor that holds ``point``
        (within :data:`TOLERANCE`), or None where it is outside."""
        p = _as_point(point, "point")
        hits = self._tree.query(Point(p), predicate="intersects")
        return int(min(hits)) if len(hits) else None

    def _connect(self, node: int, point: NDArray[np.float64], region: int) -> None:
        members, lengths = self._links(point, region)
        self.graph.add_weighted_edges_from(
            (node, int(k), float(w)) for k, w in zip(members, lengths, strict=True)
        )

    def path(self, start: ArrayLike, goal: ArrayLike) -> NDArray[np.float64]:
        """The shortest path from ``start`` to ``goal`` through the graph.

        Returns:
            (K, 2) polyline, m, K >= 2: ``start``, the corners it wraps around, ``goal``.

        Raises:
            NoPathError: ``start`` or ``goal`` is outside the reachable floor, or they lie
                in separate regions of it.
            ValueError: a point is not a finite (x, y).
        """
        s = _as_point(start, "start")
        g = _as_point(goal, "goal")
        region_s, region_g = self.region_of(s), self.region_of(g)
        for name, p, region in (("start", s, region_s), ("goal", g, region_g)):
            if region is None:
                away = shapely.distance(shapely.union_all(self._regions), Point(p))
                raise NoPathError(
                    s,
                    g,
                    f"the {name} {_fmt(p)} is outside the reachable floor ({away:.3f} m from it)",
                )
        if region_s != region_g:
            # grown regions may overlap where pieces touch at a point: look for a shared one
            shared = set(self._tree.query(Point(s), predicate="intersects").tolist()) & set(
                self._tree.query(Point(g), predicate="intersects").tolist()
            )
            if not shared:
                raise NoPathError(
                    s,
                    g,
                    f"they lie in separate regions of the reachable floor ({region_s} and "
                    f"{region_g}): no passage between them is wide enough for the clearance",
                )
            region_s = region_g = min(shared)
        assert region_s is not None
        if self._visible(region_s, s[None], g[None])[0]:
            return np.stack([s, g])
        try:
            self._connect(_START, s, region_s)
            self._connect(_GOAL, g, region_s)
            points = self.points

            def to_goal(u: int, _v: int) -> float:
                p = s if u == _START else g if u == _GOAL else points[u]
                return float(math.hypot(p[0] - g[0], p[1] - g[1]))

            nodes = nx.astar_path(self.graph, _START, _GOAL, heuristic=to_goal)
        except (nx.NetworkXNoPath, nx.NodeNotFound):
            raise NoPathError(
                s,
                g,
                "no chain of visible corners joins them (a passage narrower than "
                f"simplify={self.simplify} m may have been dropped; try simplify=0)",
            ) from None
        finally:
            for node in (_START, _GOAL):
                if node in self.graph:
                    self.graph.remove_node(node)
        inner = [self.points[k] for k in nodes[1:-1]]
        return np.stack([s, *inner, g])

    def length(self, start: ArrayLike, goal: ArrayLike) -> float:
        """The length of :meth:`path`, m (raises as it does)."""
        return _polyline_length(self.path(start, goal))

    def lengths(self, points: ArrayLike) -> NDArray[np.float64]:
        """(P, P) the length of :meth:`path` between every two of (P, 2) ``points``, m
        (raises as it does): each point is joined to the corners it sees once, and one
        search from each point reaches every other, where ``path`` joins and searches
        once per pair."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        n = len(pts)
        out = np.zeros((n, n))
        regions = [self.region_of(p) for p in pts]
        links = [
            None if r is None else self._links(p, r) for p, r in zip(pts, regions, strict=True)
        ]
        for i in range(n):
            reached: dict[int, float] = {}
            routes: dict[int, list[int]] = {}
            if links[i] is not None and len(links[i][0]):
                self.graph.add_weighted_edges_from(
                    (_START, int(k), float(w)) for k, w in zip(*links[i], strict=True)
                )
                try:
                    reached, routes = nx.single_source_dijkstra(self.graph, _START)
                finally:
                    self.graph.remove_node(_START)
            for j in range(n):
                if j == i:
                    out[i, j] = self.length(pts[i], pts[j])
                    continue
                if regions[j] != regions[i] or regions[i] is None:
                    out[i, j] = self.length(pts[i], pts[j])  # raises, or a shared region
                    continue
                if self._visible(regions[i], pts[i][None], pts[j][None])[0]:
                    out[i, j] = _polyline_length(np.stack([pts[i], pts[j]]))
                    continue
                best, via = math.inf, -1
                for k, w in zip(*links[j], strict=True):
                    total = reached.get(int(k), math.inf) + w
                    if total < best:
                        best, via = total, int(k)
                if via < 0:
                    out[i, j] = self.length(pts[i], pts[j])  # raises: no chain of corners
                    continue
                inner = [self.points[k] for k in routes[via][1:]]
                out[i, j] = _polyline_length(np.stack([pts[i], *inner, pts[j]]))
        return out

    def _links(self, point: NDArray[np.float64], region: int) -> tuple[NDArray, NDArray]:
        """The corners of ``region`` that ``point`` sees and is tangent to (as
        :meth:`_connect` joins them) and their distances, m: (L,) and (L,)."""
        members = np.flatnonzero(self._region_of == region)
        d = self.points[members] - point
        members = members[_tangent(d, self._to_prev[members], self._to_next[members])]
        ends = self.points[members]
        visible = self._visible(region, np.broadcast_to(point, ends.shape), ends)
        members = members[visible]
        lengths = np.linalg.norm(self.points[members] - point, axis=1)
        return members, lengths


def _polyline_length(path: NDArray[np.float64]) -> float:
    return float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))


def shortest_path(
    reachable: BaseGeometry, start: ArrayLike, goal: ArrayLike
) -> NDArray[np.float64]:
    """The shortest path from ``start`` to ``goal`` inside ``reachable``.

    Builds an exact :class:`RouteGraph` (``simplify=0``: every reflex corner) for this one
    query; build a :class:`RouteGraph` once where there are many.

    Args:
        reachable: where a robot's centre may be, map frame, m (Polygon or MultiPolygon).
        start: (x, y), m.
        goal: (x, y), m.

    Returns:
        (K, 2) polyline from ``start`` to ``goal``, m, covered by ``reachable`` (within
        :data:`TOLERANCE`); the shortest one that bends only at ``reachable``'s corners.

    Raises:
        NoPathError: a point is outside ``reachable``, or the two lie in separate regions.
    """
    return RouteGraph(reachable, simplify=0.0).path(start, goal)


def corridor_width(
    free: BaseGeometry, path: ArrayLike, samples_per_m: float = 2.0
) -> NDArray[np.float64]:
    """The free width across a path at samples along it: twice the distance from each sample
    to the nearest edge of ``free`` (0 where the sample is outside ``free``).

    That is the widest formation centred on the path that fits there: on the centre line of
    a straight corridor it is the corridor's width; off the centre line, near a dead end
    or at a corner it is less (the distance is to the nearest edge in any direction).

    Args:
        free: the free floor (or any polygonal region), map frame, m.
        path: (K, 2) polyline, m, K >= 1.
        samples_per_m: samples per metre of path; the samples are evenly spaced along it at
            arc lengths ``s_i = i * L / (n - 1)``, ``n = max(2, ceil(L * samples_per_m) + 1)``
            (one sample where the path has no length), both ends included.

    Returns:
        (n,) widths, m.
    """
    if not math.isfinite(samples_per_m) or samples_per_m <= 0.0:
        raise ValueError(f"samples_per_m must be finite and > 0, got {samples_per_m!r}")
    xy = np.asarray(path, dtype=float)
    if xy.ndim != 2 or xy.shape[1] != 2 or len(xy) < 1 or not np.all(np.isfinite(xy)):
        raise ValueError(f"path must be a finite (K, 2) polyline with K >= 1, got shape {xy.shape}")
    pieces = _polygons(free, "free")
    region = shapely.union_all(pieces) if pieces else Polygon()
    total = _polyline_length(xy)
    if total <= 0.0:
        samples = xy[:1]
    else:
        n = max(2, math.ceil(total * samples_per_m) + 1)
        line = LineString(xy)
        samples = shapely.get_coordinates(
            shapely.line_interpolate_point(line, np.linspace(0.0, total, n))
        )
    if region.is_empty:
        return np.zeros(len(samples))
    points = shapely.points(samples)
    shapely.prepare(region)
    inside = np.asarray(shapely.covers(region, points), dtype=bool)
    distance = np.asarray(shapely.distance(region.boundary, points), dtype=float)
    return np.where(inside, 2.0 * distance, 0.0)


def _benchmark_site(clearance: float = 0.35, quad_segs: int = 16) -> BaseGeometry:
    """The site the timings in the module's docstring were measured on: a 60 x 15 m hall with
    60 round pillars (radius 0.3 m, 16-gons) and 6 rectangular structures, shrunk by
    ``clearance`` with arcs of ``quad_segs`` segments per quarter circle (16, shapely's
    default, is what :meth:`~twin.planning.floor_map.FloorMap.reachable` uses)."""
    hall = Polygon([(0, 0), (60, 0), (60, 15), (0, 15)])
    obstacles = [
        Point(3 + 4.5 * i + 1.5 * (j % 2), 2.5 + 3.3 * j).buffer(0.3, quad_segs=4)
        for i in range(12)
        for j in range(4)
    ]
    obstacles += [Point(5 + 10 * i, 14.0).buffer(0.3, quad_segs=4) for i in range(6)]
    obstacles += [Point(10 + 10 * i, 1.0).buffer(0.3, quad_segs=4) for i in range(6)]
    obstacles += [shapely.box(7 + 9 * i, 6.8, 9 + 9 * i, 7.6) for i in range(6)]
    free = hall.difference(shapely.union_all(obstacles))
    return free.buffer(-clearance, quad_segs=quad_segs)
