"""Station scoring from coarse to fine: a quarter of the candidates scored first, then the
neighbours of the best; the best of a smooth score is still found."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from twin.planning.stations import COARSE_FROM, GRID, _candidates, _keys, _scored


@pytest.mark.parametrize("peak", [(3.2, -1.7), (-4.6, 5.1), (0.0, 9.5)])
def test_the_coarse_grid_and_the_best_ones_neighbours_find_a_smooth_scores_best(peak):
    centre = np.array([0.3, -0.2])
    candidates = _candidates(shapely.box(-20, -20, 20, 20), centre, GRID)
    assert len(candidates) > COARSE_FROM
    called: list[int] = []

    def score(xy):
        called.append(len(xy))
        # Visible fraction falling off from a peak off the coarse grid, in steps finer
        # than the ranking's.
        return np.clip(1.0 - 0.01 * np.linalg.norm(xy - np.asarray(peak), axis=1), 0, 1)

    fractions = _scored(candidates, centre, GRID, score)
    scored = np.isfinite(fractions)
    assert sum(called) == scored.sum() < 0.5 * len(candidates)
    every = score(candidates)
    np.testing.assert_array_equal(fractions[scored], every[scored])
    keys = _keys(candidates[scored], fractions[scored], centre)
    best_found = max(keys)
    assert best_found == max(_keys(candidates, every, centre))


def test_few_candidates_are_all_scored():
    centre = np.zeros(2)
    candidates = np.column_stack([np.arange(COARSE_FROM - 1) * GRID, np.zeros(COARSE_FROM - 1)])
    fractions = _scored(candidates, centre, GRID, lambda xy: np.full(len(xy), 0.5))
    assert np.all(fractions == 0.5)
