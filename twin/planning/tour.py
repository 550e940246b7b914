"""The order in which the robots visit a site's nodes (stations, cameras, data points): the
shortest open tour from a start through all of them, or a closed one back to the start.

Nodes are indices 0..n-1 and ``distance`` is either an (n, n) array or a function
``distance(i, j) -> float`` (for example the route length between two stations,
:meth:`twin.planning.route.RouteGraph.length`), in m or any other cost. It need not be
symmetric; ``inf`` marks a pair with no route.

How :func:`order_visits` solves it:

- n <= :data:`EXACT_MAX_NODES` (12): exactly, by the Held-Karp dynamic programme
  (O(2^n n^2), vectorised over the last node; about 40 ms at n = 12). Campaigns are that
  small (the paper's has five visits), and an exact order is one less source of doubt
  when comparing strategies.
- larger n: networkx's simulated annealing (``simulated_annealing_tsp``, seeded: the same
  input gives the same order) started from the nearest-neighbour tour, then 2-opt and
  or-opt moves until none shortens it (the annealing's one-node moves alone stayed up to 50 %
  above the optimum on random 14-point instances; with the polish they were within 7 %
  there, most of them exact). No guaranteed bound; about 0.3 s for 60 nodes.

An open tour from a fixed start is solved as a closed one through an extra node that every
node reaches at no cost and that leads only to the start at no cost.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from typing import Final

import networkx as nx
import numpy as np
from numpy.typing import NDArray

__all__ = ["EXACT_MAX_NODES", "brute_force_order", "order_visits", "tour_length"]

#: Up to this many nodes :func:`order_visits` is exact.
EXACT_MAX_NODES: Final[int] = 12

#: Up to this many nodes :func:`brute_force_order` agrees to run.
BRUTE_FORCE_MAX_NODES: Final[int] = 10

# The seed of the annealing for n > EXACT_MAX_NODES.
_SEED: Final[int] = 0

Distance = Callable[[int, int], float] | NDArray[np.float64]


def _check_n(n: int) -> int:
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
        raise ValueError(f"n (the number of nodes) must be an integer >= 1, got {n!r}")
    return int(n)


def _check_index(value: object, n: int, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise ValueError(f"{name} must be a node index (an integer), got {value!r}")
    if not 0 <= value < n:
        raise ValueError(f"{name}={value} is not a node index: expected 0..{n - 1}")
    return int(value)


def _matrix(distance: Distance, n: int) -> NDArray[np.float64]:
    """``distance`` as an (n, n) float array, checked: no NaN, nothing negative."""
    if callable(distance):
        d = np.zeros((n, n))
        for i in range(n):
            for j in range(n):
                if i != j:
                    d[i, j] = float(distance(i, j))
    else:
        d = np.array(distance, dtype=float)
        if d.shape != (n, n):
            raise ValueError(f"distance must be an ({n}, {n}) array, got shape {d.shape}")
    off = ~np.eye(n, dtype=bool)
    bad = np.argwhere(off & (np.isnan(d) | (d < 0.0)))
    if len(bad):
        i, j = bad[0]
        raise ValueError(
            f"distance({i}, {j}) = {float(d[i, j])!r}: expected a number >= 0 (inf for no route)"
        )
    np.fill_diagonal(d, 0.0)
    return d


def _check_order(order: Sequence[int], n: int, start: int, name: str = "fixed") -> list[int]:
    """``order`` as a list, checked to be each node 0..n-1 exactly once, from ``start``."""
    try:
        items = list(order)
    except TypeError:
        raise ValueError(f"{name} must be a sequence of node indices, got {order!r}") from None
    out = [_check_index(k, n, f"{name}[{pos}]") for pos, k in enumerate(items)]
    seen: set[int] = set()
    for pos, k in enumerate(out):
        if k in seen:
            raise ValueError(f"{name} visits node {k} twice (again at position {pos}): {out}")
        seen.add(k)
    missing = sorted(set(range(n)) - seen)
    if missing:
        raise ValueError(f"{name} misses node(s) {missing} of 0..{n - 1}: {out}")
    if out[0] != start:
        raise ValueError(f"{name} starts at node {out[0]}, expected the start node {start}")
    return out


def tour_length(distance: Distance, order: Sequence[int], return_to_start: bool = False) -> float:
    """The length of visiting ``order`` in turn (plus the way back to ``order[0]`` with
    ``return_to_start``). ``order`` may visit a node more than once (e.g. 0-1-2-1-0)."""
    nodes = [int(k) for k in order]
    if not nodes:
        raise ValueError("order is empty: expected at least one node index")
    if not callable(distance):
        d = np.asarray(distance, dtype=float)
        if d.ndim != 2 or d.shape[0] != d.shape[1]:
            raise ValueError(f"distance must be a square array, got shape {d.shape}")
        for pos, k in enumerate(nodes):
            _check_index(k, d.shape[0], f"order[{pos}]")
        distance_of = lambda i, j: float(d[i, j])  # noqa: E731
    else:
        distance_of = distance
    legs = list(itertools.pairwise(nodes))
    if return_to_start and len(nodes) > 1:
        legs.append((nodes[-1], nodes[0]))
    return float(sum(0.0 if i == j else float(distance_of(i, j)) for i, j in legs))


def brute_force_order(
    distance: Distance, n: int, start: int = 0, return_to_start: bool = False
) -> list[int]:
    """The shortest order by trying every permutation (for tests; n <= 10): the first of the
    shortest in lexicographic order of the nodes after ``start``."""
    n = _check_n(n)
    start = _check_index(start, n, "start")
    if n > BRUTE_FORCE_MAX_NODES:
        raise ValueError(
            f"n={n} is too many for brute force (at most {BRUTE_FORCE_MAX_NODES} nodes)"
        )
    d = _matrix(distance, n)
    others = [k for k in range(n) if k != start]
    best, best_length = [start, *others], math.inf
    for perm in itertools.permutations(others):
        order = [start, *perm]
        length = tour_length(d, order, return_to_start)
        if length < best_length:
            best, best_length = order, length
    return best


def order_visits(
    distance: Callable[[int, int], float] | NDArray,
    n: int,
    *,
    start: int = 0,
    return_to_start: bool = False,
    fixed: Sequence[int] | None = None,
) -> list[int]:
    """The order that visits every node once, from ``start``, shortest in total.

    Args:
        distance: (n, n) array or ``distance(i, j)``, the cost from node i to node j
            (>= 0; ``inf`` where there is no route). A function is called once per pair.
        n: the number of nodes (0..n-1).
        start: the node the tour starts from.
        return_to_start: count the way back from the last node to ``start`` (a closed
            tour); it is not repeated in the returned list.
        fixed: an order the user wants kept (each node once, starting at ``start``):
            returned unchanged after it is checked, and ``distance`` is not used. A route
            that passes a camera twice (the paper's 1-2-3-2-1) has a node per visit.

    Returns:
        The n node indices in the order of the visits, ``start`` first.

    Raises:
        ValueError: n < 1, ``start`` out of range, a ``fixed`` order with a repeated,
            missing or unknown node, a ``distance`` of the wrong shape or with a negative
            or NaN entry, or every order has an infinite length (naming the problem).
    """
    n = _check_n(n)
    start = _check_index(start, n, "start")
    if fixed is not None:
        return _check_order(fixed, n, start)
    if n == 1:
        return [start]
    d = _matrix(distance, n)
    order = _held_karp(d, start, return_to_start) if n <= EXACT_MAX_NODES else None
    if order is None:
        order = _annealed(d, start, return_to_start)
    if not math.isfinite(tour_length(d, order, return_to_start)):
        unreachable = [(int(i), int(j)) for i, j in np.argwhere(~np.isfinite(d))][:5]
        raise ValueError(
            f"no order visits all {n} nodes at a finite cost: distance is inf between {unreachable}"
        )
    return order


def _held_karp(d: NDArray[np.float64], start: int, closed: bool) -> list[int]:
    """The exact shortest order by the Held-Karp dynamic programme.

    ``cost[mask, k]``: the shortest path from ``start`` through the nodes of ``mask`` (a
    bit set over ``others``), ending at ``others[k]`` (a member of ``mask``)."""
    n = len(d)
    others = np.array([k for k in range(n) if k != start])
    m = len(others)
    sub = d[np.ix_(others, others)]
    full = (1 << m) - 1
    cost = np.full((full + 1, m), np.inf)
    parent = np.full((full + 1, m), -1, dtype=np.int64)
    bits = 1 << np.arange(m)
    cost[bits, np.arange(m)] = d[start, others]
    for mask in range(1, full + 1):
        row = cost[mask]
        outside = np.flatnonzero((mask & bits) == 0)
        if len(outside) == 0 or not np.any(np.isfinite(row)):
            continue
        candidates = row[:, None] + sub[:, outside]  # (last, next)
        best = np.argmin(candidates, axis=0)
        value = candidates[best, np.arange(len(outside))]
        targets = mask | bits[outside]
        better = value < cost[targets, outside]
        cost[targets[better], outside[better]] = value[better]
        parent[targets[better], outside[better]] = best[better]
    final = cost[full] + (d[others, start] if closed else 0.0)
    last = int(np.argmin(final))
    tail: list[int] = []
    mask = full
    while last >= 0:
        tail.append(int(others[last]))
        last, mask = int(parent[mask, last]), mask & ~(1 << last)
    return [start, *reversed(tail)]


def _annealed(d: NDArray[np.float64], start: int, closed: bool) -> list[int]:
    """A short order: networkx's simulated annealing from the nearest-neighbour tour, both
    polished by :func:`_improved`, the shorter of the two."""
    n = len(d)
    finite = d[np.isfinite(d)]
    big = 10.0 * (float(finite.sum()) + 1.0)  # stands for inf: more than any finite tour
    cost = np.where(np.isfinite(d), d, big)
    graph = nx.DiGraph()
    graph.add_weighted_edges_from(
        (i, j, float(cost[i, j])) for i in range(n) for j in range(n) if i != j
    )
    order = [start]
    left = set(range(n)) - {start}
    while left:  # nearest neighbour
        here = order[-1]
        nearest = min(left, key=lambda k: (cost[here, k], k))
        order.append(nearest)
        left.remove(nearest)
    cycle = [*order, start]
    if not closed:
        # an extra node that every node reaches at no cost and that leads only to start:
        # the shortest cycle through it is the shortest open path from start
        extra = n
        graph.add_weighted_edges_from((k, extra, 0.0) for k in range(n))
        graph.add_weighted_edges_from((extra, k, 0.0 if k == start else big) for k in range(n))
        cycle = [*order, extra, start]
    scale = float(np.mean(cost[~np.eye(n, dtype=bool)])) or 1.0
    best = nx.approximation.simulated_annealing_tsp(
        graph,
        cycle,
        source=start,
        move="1-0",
        temp=scale,
        N_inner=100,
        max_iterations=20,
        alpha=0.05,
        seed=_SEED,
    )
    tour = [k for k in best[:-1] if k != n]
    candidates = [_improved(cost, order, closed), _improved(cost, tour, closed)]
    return min(candidates, key=lambda o: tour_length(cost, o, closed))


def _length(cost: NDArray[np.float64], order: NDArray[np.intp], closed: bool) -> float:
    total = float(cost[order[:-1], order[1:]].sum())
    return total + float(cost[order[-1], order[0]]) if closed else total


def _improved(cost: NDArray[np.float64], order: list[int], closed: bool) -> list[int]:
    """``order`` improved by 2-opt (reverse a stretch) and or-opt (move a stretch of 1-3
    nodes) moves, first improvement, until none shortens it; ``order[0]`` stays first."""
    tour = np.asarray(order, dtype=np.intp)
    n = len(tour)
    best = _length(cost, tour, closed)
    improved = True
    while improved:
        improved = False
        for i in range(1, n - 1):
            for j in range(i + 1, n):
                candidate = tour.copy()
                candidate[i : j + 1] = tour[i : j + 1][::-1]
                length = _length(cost, candidate, closed)
                if length < best - 1e-12 * max(best, 1.0):
                    tour, best, improved = candidate, length, True
        for size in (1, 2, 3):
            for i in range(1, n - size + 1):
                stretch = tour[i : i + size]
                rest = np.concatenate([tour[:i], tour[i + size :]])
                for at in range(1, len(rest) + 1):
                    if at == i:
                        continue
                    candidate = np.concatenate([rest[:at], stretch, rest[at:]])
                    length = _length(cost, candidate, closed)
                    if length < best - 1e-12 * max(best, 1.0):
                        tour, best, improved = candidate, length, True
                        break
    return [int(k) for k in tour]
