"""The order of the visits: exact for small n (against brute force), closed tours, kept
orders, bad input."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from twin.planning.tour import (
    _held_karp,
    brute_force_order,
    order_visits,
    tour_length,
)


def _points(seed: int, n: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(0.0, 100.0, size=(n, 2))


def _euclid(points: np.ndarray) -> np.ndarray:
    return np.linalg.norm(points[:, None] - points[None], axis=-1)


@pytest.mark.parametrize("return_to_start", [False, True])
@pytest.mark.parametrize("seed", range(30))
def test_order_is_never_longer_than_brute_force(seed: int, return_to_start: bool) -> None:
    d = _euclid(_points(seed, 7))
    start = seed % 7
    order = order_visits(d, 7, start=start, return_to_start=return_to_start)
    assert order[0] == start
    assert sorted(order) == list(range(7))
    best = brute_force_order(d, 7, start=start, return_to_start=return_to_start)
    assert tour_length(d, order, return_to_start) <= (tour_length(d, best, return_to_start) + 1e-9)


def test_asymmetric_distances_are_solved_exactly() -> None:
    rng = np.random.default_rng(7)
    for _ in range(5):
        d = rng.uniform(1.0, 10.0, size=(6, 6))
        for closed in (False, True):
            order = order_visits(d, 6, return_to_start=closed)
            best = brute_force_order(d, 6, return_to_start=closed)
            assert tour_length(d, order, closed) == pytest.approx(tour_length(d, best, closed))


def test_a_closed_tour_of_a_square_is_its_perimeter() -> None:
    corners = np.array([[0, 0], [0, 2], [2, 0], [2, 2]], dtype=float)
    d = _euclid(corners)
    order = order_visits(d, 4, start=3, return_to_start=True)
    assert order[0] == 3
    assert tour_length(d, order, return_to_start=True) == pytest.approx(8.0)
    # open: three sides
    assert tour_length(d, order_visits(d, 4, start=3), False) == pytest.approx(6.0)


def test_points_on_a_line_are_visited_in_order() -> None:
    x = np.array([0.0, 3.0, 1.0, 2.0])
    d = np.abs(x[:, None] - x[None])
    assert order_visits(d, 4) == [0, 2, 3, 1]
    assert order_visits(lambda i, j: float(abs(x[i] - x[j])), 4) == [0, 2, 3, 1]


def test_many_nodes_are_ordered_close_to_the_optimum() -> None:
    for seed in range(4):
        d = _euclid(_points(100 + seed, 14))
        for closed in (False, True):
            order = order_visits(d, 14, return_to_start=closed)
            assert order[0] == 0
            assert sorted(order) == list(range(14))
            exact = _held_karp(d, 0, closed)
            assert tour_length(d, order, closed) <= 1.10 * tour_length(d, exact, closed)


def test_a_fixed_order_is_kept() -> None:
    d = _euclid(_points(3, 5))
    fixed = [0, 1, 2, 3, 4]  # e.g. cameras 1-2-3-2-1, a node per visit
    assert order_visits(d, 5, fixed=fixed) == fixed
    assert order_visits(None, 5, start=2, fixed=(2, 0, 1, 4, 3)) == [2, 0, 1, 4, 3]


@pytest.mark.parametrize(
    ("fixed", "message"),
    [
        ([0, 1, 1, 3], r"visits node 1 twice"),
        ([0, 1, 2], r"misses node\(s\) \[3\]"),
        ([0, 1, 2, 7], r"fixed\[3\]=7 is not a node index"),
        ([0, 1, 2, "x"], r"fixed\[3\] must be a node index"),
        ([1, 0, 2, 3], r"starts at node 1, expected the start node 0"),
    ],
)
def test_a_bad_fixed_order_is_refused(fixed: list, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        order_visits(np.zeros((4, 4)), 4, fixed=fixed)


def test_bad_input_is_refused() -> None:
    d = np.ones((3, 3))
    with pytest.raises(ValueError, match=r"n \(the number of nodes\)"):
        order_visits(d, 0)
    with pytest.raises(ValueError, match=r"start=3 is not a node index: expected 0..2"):
        order_visits(d, 3, start=3)
    with pytest.raises(ValueError, match=r"start=-1"):
        brute_force_order(d, 3, start=-1)
    with pytest.raises(ValueError, match=r"\(4, 4\) array"):
        order_visits(d, 4)
    with pytest.raises(ValueError, match=r"distance\(0, 1\) = -1.0"):
        order_visits(np.array([[0, -1.0], [1, 0]]), 2)
    with pytest.raises(ValueError, match="too many for brute force"):
        brute_force_order(np.ones((11, 11)), 11)
    with pytest.raises(ValueError, match=r"order\[1\]=5"):
        tour_length(d, [0, 5])


def test_infinite_distances() -> None:
    d = np.full((4, 4), np.inf)
    for i, j in itertools.pairwise(range(4)):
        d[i, j] = 1.0
    assert order_visits(d, 4) == [0, 1, 2, 3]  # the only finite order
    with pytest.raises(ValueError, match="finite cost"):
        order_visits(d, 4, return_to_start=True)


def test_one_node_and_tour_length_with_repeated_visits() -> None:
    assert order_visits(np.zeros((1, 1)), 1) == [0]
    d = _euclid(np.array([[0.0, 0.0], [1.0, 0.0], [3.0, 0.0]]))
    assert tour_length(d, [0, 1, 2, 1, 0]) == pytest.approx(6.0)
    assert tour_length(d, [0, 2], return_to_start=True) == pytest.approx(6.0)
    assert tour_length(d, [1]) == 0.0
