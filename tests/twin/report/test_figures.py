"""The figures, one by one, and the clipping of camera views to the hall."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from twin.report import error_vs_distance, residuals, top_view
from twin.report.figures import clip_polygon, obstacle_corners
from twin.scenario import Scenario


def test_clip_polygon_to_a_rectangle() -> None:
    square = np.array([[-1.0, -1.0], [3.0, -1.0], [3.0, 3.0], [-1.0, 3.0]])
    clipped = clip_polygon(square, (0.0, 2.0), (0.0, 1.0))
    np.testing.assert_allclose(np.sort(clipped, axis=0).min(axis=0), [0.0, 0.0])
    np.testing.assert_allclose(clipped.max(axis=0), [2.0, 1.0])
    assert len(clip_polygon(square + 10.0, (0.0, 2.0), (0.0, 1.0))) == 0
    assert clip_polygon(np.zeros((0, 2)), (0.0, 1.0), (0.0, 1.0)).shape == (0, 2)


def test_obstacle_corners(scenario: Scenario) -> None:
    island = next(o for o in scenario.space.obstacles if o.name == "island")
    corners = obstacle_corners(island)
    np.testing.assert_allclose(corners.min(axis=0), [20.0, 0.7])
    np.testing.assert_allclose(corners.max(axis=0), [32.0, 3.3])


def test_each_figure_writes_a_png(
    scenario: Scenario, results: dict[str, Any], tmp_path: Path
) -> None:
    paths = [
        top_view(scenario, results, tmp_path / "a" / "top.png"),
        error_vs_distance(results, tmp_path / "b.png"),
        residuals(results, tmp_path / "c.png"),
    ]
    for path in paths:
        assert path.read_bytes()[:4] == b"\x89PNG"


def test_figures_accept_odd_values(scenario: Scenario, tmp_path: Path) -> None:
    odd = {
        "calibrations": [
            {"camera": "cam9", "visit": None, "residuals_px": [], "data_points_xy": "bad"},
            {"camera": "cam1", "visit": 1, "distance_travelled_m": None, "errors": None},
            {"camera": "cam2", "visit": 1, "distance_travelled_m": 3.0, "errors": {"world": None}},
        ],
        "parent_track": None,
        "skipped_visits": [{"camera": "cam3", "visit": 1, "station": None}],
    }
    for path in (
        top_view(scenario, odd, tmp_path / "t.png"),
        error_vs_distance(odd, tmp_path / "e.png"),
        residuals(odd, tmp_path / "r.png"),
    ):
        assert path.stat().st_size > 0
