"""The environment's top view as an RGB array (headless: matplotlib's Agg canvas)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse
from numpy.typing import NDArray

from twin.batch.execute import BatchRun
from twin.report.figures import camera_colours, draw_cameras, draw_space
from twin.scenario.schema import Scenario

ELLIPSE_SCALE = 100.0
"""The parent's covariance ellipse (2 sigma) is drawn this many times its size."""

DPI = 80


def top_view_rgb(
    scenario: Scenario,
    batch: BatchRun,
    track: Sequence[NDArray[np.float64]],
    camera_errors_mm: Mapping[str, float],
    row: int = 0,
) -> NDArray[np.uint8]:
    """(H, W, 3) the site from above: walls, obstacles, cameras and their views (a
    calibrated camera's name carries its true error), the route, the parent's estimated
    track, the robots where they truly stand, and the parent's covariance ellipse."""
    space = scenario.space
    (x0, x1), (y0, y1) = space.x_range, space.y_range
    width = 8.0
    height = max(2.5, min(8.0, width * (y1 - y0) / (x1 - x0) + 1.0))
    fig = Figure(figsize=(width, height), dpi=DPI, layout="constrained")
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    colours = camera_colours(scenario, {})
    draw_space(ax, scenario)
    draw_cameras(ax, scenario, colours)
    route = np.asarray(scenario.route.waypoints, dtype=float)
    ax.plot(route[:, 0], route[:, 1], ls="--", color="0.5", lw=0.8, zorder=4)
    path = np.asarray(track, dtype=float).reshape(-1, 3)
    ax.plot(path[:, 0], path[:, 1], color="black", lw=1.0, marker="o", ms=2, zorder=6)
    for name, robot in batch.robots.items():
        x, y, _ = robot.true[row]
        parent = name == batch.plan.parent
        ax.plot(
            [x],
            [y],
            marker="s" if parent else "o",
            ms=7 if parent else 5,
            color="tab:red" if parent else "tab:blue",
            mec="black",
            zorder=9,
        )
    estimate = batch.cps.parent
    cov = estimate.covariance[row, 1:3, 1:3]
    values, vectors = np.linalg.eigh(cov)
    angle = float(np.degrees(np.arctan2(vectors[1, 1], vectors[0, 1])))
    w, h = 2 * 2 * ELLIPSE_SCALE * np.sqrt(np.clip(values[::-1], 0.0, None))
    centre = estimate.translation[row, :2]
    ax.add_patch(
        Ellipse(tuple(centre), w, h, angle=angle, fc="none", ec="tab:red", lw=1.0, zorder=10)
    )
    for cam in scenario.cameras:
        if cam.name in camera_errors_mm:
            ax.annotate(
                f"{camera_errors_mm[cam.name]:.0f} mm",
                cam.position[:2],
                xytext=(4, -10),
                textcoords="offset points",
                fontsize=7,
            )
    ax.set_xlim(x0 - 1, x1 + 1)
    ax.set_ylim(y0 - 1, y1 + 1)
    ax.set_aspect("equal")
    ax.set_title(
        f"{scenario.name}: {float(batch.distance[row]):.1f} m travelled "
        f"(covariance x {ELLIPSE_SCALE:g}, 2 sigma)",
        fontsize=9,
    )
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()
