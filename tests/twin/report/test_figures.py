"""The figures, one by one, read back: what each draws, and the clipping of camera views
to the hall."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib import colors

from tests.twin.report.figure_checks import Saved, pixels_of
from twin.report import error_vs_distance, paper, residuals, top_view
from twin.report.figures import clip_polygon, obstacle_corners
from twin.report.reading import planned_visits
from twin.scenario import Scenario

CAMERA_COLOURS = {"cam1": "tab:blue", "cam2": "tab:orange", "cam3": "tab:green"}
"""Matplotlib's first three colours, one a camera in the scenario's order."""


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


def test_each_figure_draws_what_it_was_given(
    scenario: Scenario, results: dict[str, Any], tmp_path: Path, saved: dict[str, Saved]
) -> None:
    top_view(scenario, results, tmp_path / "a" / "top.png")
    error_vs_distance(results, tmp_path / "b.png")
    residuals(results, tmp_path / "c.png")
    colours = CAMERA_COLOURS
    cals = results["calibrations"]

    # The hall from above: the route and the parent's estimated stations as given, and each
    # camera's marker (and its child data) in the camera's colour in the PNG.
    top = saved["top.png"]
    (route,) = top.lines("route")
    np.testing.assert_array_equal(route.get_xydata(), scenario.route.waypoints)
    (track,) = top.lines("parent, estimated (stations)")
    np.testing.assert_array_equal(track.get_xydata(), results["parent_track"]["estimated"])
    img = top.check_png()
    for cam in scenario.cameras:
        assert pixels_of(img, colours[cam.name]) > 50, cam.name

    # Table III as a plot: the twin's world pixel errors at their distances (camera 3 has
    # no reference set, so no world error).
    errors = saved["b.png"]
    (world_px, _) = errors.lines("twin, world")  # pixel axes first, then 3D
    with_world = sorted((c["distance_travelled_m"], c["errors"]["world"]["pixel_mean"])
                        for c in cals if c["errors"]["world"])  # fmt: skip
    np.testing.assert_array_equal(world_px.get_xydata(), with_world)
    errors.check_png()

    # The residuals: one axes a calibration, its dots the residuals, its title their RMS,
    # the dots in the camera's colour.
    res = saved["c.png"]
    for ax, cal in zip(res.figure.axes, cals, strict=True):
        (dots,) = [ln for ln in ax.get_lines() if ln.get_marker() == "."]
        r = np.asarray(cal["residuals_px"])
        np.testing.assert_array_equal(dots.get_xydata(), r)
        rms = np.sqrt(np.mean(np.sum(r**2, axis=1)))
        assert f"RMS {rms:.3g} px (N={len(r)})" in ax.get_title()
        assert colors.same_color(dots.get_color(), colours[cal["camera"]])
    img = res.check_png()
    for name in ("cam1", "cam2", "cam3"):
        assert pixels_of(img, colours[name]) > 50, name


def test_figures_accept_odd_values(
    scenario: Scenario, tmp_path: Path, saved: dict[str, Saved]
) -> None:
    odd = {
        "calibrations": [
            {"camera": "cam9", "visit": None, "residuals_px": [], "data_points_xy": "bad"},
            {"camera": "cam1", "visit": 1, "distance_travelled_m": None, "errors": None},
            {"camera": "cam2", "visit": 1, "distance_travelled_m": 3.0, "errors": {"world": None}},
        ],
        "parent_track": None,
        "skipped_visits": [{"camera": "cam3", "visit": 1, "station": None}],
    }
    top_view(scenario, odd, tmp_path / "t.png")
    error_vs_distance(odd, tmp_path / "e.png")
    residuals(odd, tmp_path / "r.png")
    for figure in saved.values():
        figure.check_png()
    # No track, and camera 3's visit drawn as skipped (a red cross) at its planned station.
    top = saved["t.png"]
    assert not top.lines("parent, estimated (stations)")
    (skipped,) = top.lines("station (skipped)")
    assert (skipped.get_marker(), skipped.get_color()) == ("X", "red")
    planned = dict(planned_visits(scenario))[("cam3", 1)]
    np.testing.assert_array_equal(skipped.get_xydata(), [planned])
    # No twin errors with a distance: only the paper's camera 2 (1st), placed at this run's
    # distance for that visit.
    errors = saved["e.png"]
    assert not errors.lines("twin, world")
    (world_px, _) = errors.lines("paper, world (paper's values at this run's distances)")
    np.testing.assert_array_equal(
        world_px.get_xydata(), [[3.0, paper.table_iii("cam2", 1).world_pixel]]
    )
    # No residuals: said on each calibration's axes.
    assert saved["r.png"].texts().count("not available") == 3
