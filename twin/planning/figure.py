"""The figure of a planned site: the map's floor as the scenario sees it, the cameras and
their views, each camera's station and the parent's route, and (when a run predicted
them) each camera's predicted world-frame position error as a colour."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import matplotlib as mpl
import numpy as np
from matplotlib.figure import Figure

from twin.report.figures import draw_cameras, draw_space, save_figure
from twin.scenario.schema import Scenario


def plan_figure(
    scenario: Scenario,
    path: str | Path,
    predicted_mm: Mapping[str, float] | None = None,
) -> Path:
    """Draw the plan of ``scenario`` (a planned site) into ``path`` (PNG).

    Args:
        scenario: the planned scenario (W).
        path: the image to write.
        predicted_mm: each camera's predicted world-frame position error (RMS, mm), to
            colour the cameras by; None draws them in one colour.
    """
    space = scenario.space
    (x0, x1), (y0, y1) = space.x_range, space.y_range
    aspect = (y1 - y0) / max(x1 - x0, 1e-9)
    width = 11.0
    fig = Figure(figsize=(width, max(3.5, min(width * aspect + 1.2, 14.0))))
    ax = fig.add_subplot(1, 1, 1)
    draw_space(ax, scenario)
    colours: dict[str, str] = {}
    if predicted_mm:
        values = np.array(list(predicted_mm.values()))
        norm = mpl.colors.Normalize(vmin=0.0, vmax=float(values.max()) or 1.0)
        cmap = mpl.colormaps["viridis"]
        colours = {c: mpl.colors.to_hex(cmap(norm(v))) for c, v in predicted_mm.items()}
        mappable = mpl.cm.ScalarMappable(norm=norm, cmap=cmap)
        fig.colorbar(mappable, ax=ax, label="predicted camera position error, RMS [mm]")
    draw_cameras(ax, scenario, colours)
    route = np.asarray(scenario.route.waypoints)
    ax.plot(route[:, 0], route[:, 1], "-", color="tab:red", lw=1.4, zorder=5, label="route")
    ax.plot(*route[0], "s", color="tab:red", ms=8, zorder=6, label="start (W's origin)")
    for k, visit in enumerate(scenario.calibration.visits):
        x, y = visit.station
        ax.plot(x, y, "o", color="black", ms=6, zorder=6)
        ax.annotate(
            f"{k + 1}: {visit.camera}",
            (x, y),
            xytext=(4, 4),
            textcoords="offset points",
            fontsize=8,
            zorder=7,
        )
    for child in scenario.robots.children:
        ax.plot(*child.start_xy, "^", color="tab:blue", ms=6, zorder=6)
    ax.set_xlim(x0 - 1.0, x1 + 1.0)
    ax.set_ylim(y0 - 1.0, y1 + 1.0)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m] (W)")
    ax.set_ylabel("y [m] (W)")
    length = float(np.sum(np.linalg.norm(np.diff(route, axis=0), axis=1)))
    ax.set_title(
        f"{scenario.name}: {len(scenario.cameras)} cameras, "
        f"{len(scenario.calibration.visits)} visits, route {length:.1f} m"
    )
    ax.legend(loc="upper right", fontsize=8)
    return save_figure(fig, path)
