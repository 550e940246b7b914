"""Figures of a campaign: the hall from above, errors against distance, residuals.

Figures are drawn on :class:`matplotlib.figure.Figure` objects rendered by the Agg canvas,
without pyplot: nothing opens a window and nothing global is changed, so figures can be
written from any thread or a headless machine. Each function writes one PNG and returns
its path; missing or empty parts of the results (no calibrations, no world errors, no
track) leave their part of the figure empty or say "not available" on it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure
from matplotlib.patches import Polygon, Rectangle
from numpy.typing import NDArray

from twin.report import paper
from twin.report.reading import (
    Results,
    calibrations,
    error,
    mapping,
    number,
    planned_visits,
    points_xy,
    skipped_visits,
    visit_key,
    visit_name,
)
from twin.scenario.geometry import floor_view_corners
from twin.scenario.schema import Obstacle, Scenario

DPI = 120

PALETTE = (
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#d62728",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#7f7f7f",
    "#bcbd22",
    "#17becf",
)


def camera_colours(scenario: Scenario | None, results: Results) -> dict[str, str]:
    """A colour per camera name: the scenario's cameras first, then any others in results."""
    names: list[str] = [c.name for c in scenario.cameras] if scenario is not None else []
    for entry in calibrations(results) + skipped_visits(results):
        name = visit_key(entry)[0]
        if name not in names:
            names.append(name)
    return {name: PALETTE[i % len(PALETTE)] for i, name in enumerate(names)}


def save_figure(fig: Figure, path: str | Path) -> Path:
    """Write ``fig`` as a PNG at ``path`` (folders created) with the Agg canvas."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=DPI, bbox_inches="tight", format="png")
    return path


def no_data(ax: Axes, text: str) -> None:
    """Say on ``ax`` that its data are not available."""
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, color="0.4")


# -- geometry helpers ------------------------------------------------------------------------
def clip_polygon(
    polygon: NDArray[np.float64], x_range: Sequence[float], y_range: Sequence[float]
) -> NDArray[np.float64]:
    """Clip a polygon to an axis-aligned rectangle (shapely's intersection).

    Args:
        polygon: (K, 2) vertices in order, m.
        x_range, y_range: (min, max) of the rectangle, m.

    Returns:
        (M, 2) vertices of the clipped polygon, without the closing repeat (M may be 0).
    """
    pts = np.asarray(polygon, dtype=float).reshape(-1, 2)
    if len(pts) < 3:
        return np.zeros((0, 2))
    clipped = (
        shapely.Polygon(pts)
        .buffer(0)
        .intersection(shapely.box(x_range[0], y_range[0], x_range[1], y_range[1]))
    )
    if clipped.is_empty or clipped.geom_type != "Polygon":
        parts = [g for g in getattr(clipped, "geoms", []) if g.geom_type == "Polygon"]
        if not parts:
            return np.zeros((0, 2))
        clipped = max(parts, key=lambda g: g.area)
    return np.asarray(clipped.exterior.coords, dtype=float)[:-1]


def obstacle_corners(obstacle: Obstacle) -> NDArray[np.float64]:
    """(4, 2) corners of an obstacle's footprint, m, counter-clockwise."""
    hx, hy = obstacle.size[0] / 2.0, obstacle.size[1] / 2.0
    local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    c, s = math.cos(obstacle.yaw), math.sin(obstacle.yaw)
    rot = np.array([[c, -s], [s, c]])
    return local @ rot.T + np.asarray(obstacle.center, dtype=float)


# -- top view --------------------------------------------------------------------------------
def draw_space(ax: Axes, scenario: Scenario) -> None:
    """The walls, the inaccessible areas (stairs hatched) and the tilted floor patches."""
    space = scenario.space
    (x0, x1), (y0, y1) = space.x_range, space.y_range
    t = space.wall_thickness
    ax.add_patch(
        Rectangle(
            (x0 - t, y0 - t), x1 - x0 + 2 * t, y1 - y0 + 2 * t, fc="0.35", ec="none", zorder=0
        )
    )
    ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fc="white", ec="black", lw=0.8, zorder=0))
    for i, patch in enumerate(space.floor_patches):
        ax.add_patch(
            Rectangle(
                (patch.center[0] - patch.size[0] / 2, patch.center[1] - patch.size[1] / 2),
                patch.size[0],
                patch.size[1],
                fc="tan",
                ec="none",
                alpha=0.3,
                zorder=1,
                label="tilted floor" if i == 0 else None,
            )
        )
    # One collection for the boxes (a map's floor is thousands of them: a patch each takes
    # seconds to draw), a hatched patch for each staircase.
    boxes = [obstacle_corners(ob) for ob in space.obstacles if ob.kind == "box"]
    style = {"facecolor": "0.7", "edgecolor": "0.4", "linewidth": 0.6, "zorder": 2}
    if boxes:
        ax.add_collection(PolyCollection(boxes, closed=True, label="inaccessible", **style))
    for i, obstacle in enumerate(ob for ob in space.obstacles if ob.kind == "stairs"):
        ax.add_patch(
            Polygon(
                obstacle_corners(obstacle),
                closed=True,
                fc="0.7",
                ec="0.4",
                lw=0.6,
                hatch="//",
                zorder=2,
                label="inaccessible" if i == 0 and not boxes else None,
            )
        )


def draw_cameras(ax: Axes, scenario: Scenario, colours: Mapping[str, str]) -> None:
    """Each camera with its name and its view of the floor (clipped to the space)."""
    space = scenario.space
    for cam in scenario.cameras:
        colour = colours.get(cam.name, "black")
        try:
            corners = floor_view_corners(cam.tsai(), space.floor_z)
        except (ValueError, np.linalg.LinAlgError):
            corners = np.zeros((0, 2))
        view = clip_polygon(corners, space.x_range, space.y_range)
        if len(view) >= 3:
            ax.add_patch(
                Polygon(view, closed=True, fc=colour, ec=colour, alpha=0.15, lw=1.0, zorder=3)
            )
        x, y = cam.position[0], cam.position[1]
        ax.plot([x], [y], marker="^", ms=9, color=colour, mec="black", mew=0.6, ls="", zorder=8)
        ax.annotate(
            cam.name,
            (x, y),
            xytext=(4, 4),
            textcoords="offset points",
            fontsize=8,
            color=colour,
            fontweight="bold",
            zorder=9,
        )


def _draw_tracks(ax: Axes, scenario: Scenario, results: Results) -> None:
    route = np.asarray(scenario.route.waypoints, dtype=float)
    ax.plot(route[:, 0], route[:, 1], ls="--", color="0.3", lw=1.0, label="route", zorder=4)
    track = mapping(results.get("parent_track"))
    estimated = points_xy(track.get("estimated"))
    true = points_xy(track.get("true"))
    if len(true):
        ax.plot(
            true[:, 0], true[:, 1], color="green", lw=0.8, alpha=0.8, label="parent, true", zorder=5
        )
    if len(estimated):
        ax.plot(
            estimated[:, 0],
            estimated[:, 1],
            color="black",
            lw=1.0,
            marker="o",
            ms=2.5,
            label="parent, estimated (stations)",
            zorder=6,
        )


def _draw_visits(
    ax: Axes, scenario: Scenario, results: Results, colours: Mapping[str, str]
) -> None:
    done = {visit_key(e): e for e in calibrations(results)}
    skipped = {visit_key(e): e for e in skipped_visits(results)}
    labelled: set[str] = set()
    for order, (key, station) in enumerate(planned_visits(scenario), start=1):
        entry = done.get(key)
        xy = station
        if entry is not None and len(points_xy([entry.get("station")])):
            xy = tuple(points_xy([entry.get("station")])[0])
        colour = colours.get(key[0], "black")
        if entry is not None:
            style = dict(marker="s", color=colour, mec="black")
            kind = "calibrated"
        elif key in skipped:
            style = dict(marker="X", color="red", mec="black")
            kind = "skipped"
        else:
            style = dict(marker="s", color="none", mec=colour)
            kind = "not calibrated"
        ax.plot(
            [xy[0]],
            [xy[1]],
            ls="",
            ms=8,
            mew=0.7,
            zorder=10,
            label=f"station ({kind})" if kind not in labelled else None,
            **style,
        )
        labelled.add(kind)
        ax.annotate(
            str(order),
            xy,
            xytext=(5, -11),
            textcoords="offset points",
            fontsize=8,
            fontweight="bold",
            zorder=11,
        )


def _draw_data_points(ax: Axes, results: Results, colours: Mapping[str, str]) -> None:
    seen: set[str] = set()
    for entry in calibrations(results):
        pts = points_xy(entry.get("data_points_xy"))
        if not len(pts):
            continue
        name = visit_key(entry)[0]
        ax.plot(
            pts[:, 0],
            pts[:, 1],
            ls="",
            marker=".",
            ms=3,
            color=colours.get(name, "black"),
            alpha=0.8,
            zorder=7,
            label=f"child data, {name}" if name not in seen else None,
        )
        seen.add(name)


def top_view(scenario: Scenario, results: Results, path: str | Path) -> Path:
    """The hall from above, like the paper's Figs. 10 and 12.

    Draws the walls, the inaccessible areas (grey; stairs hatched), the tilted floor
    patches, each camera with its name and its view of the floor (clipped to the hall),
    the planned route (dashed), the parent's estimated track with its stations and its
    true track when known, the calibration stations numbered in the order of the visits
    (skipped ones as red crosses), and each calibration's child data points coloured by
    camera.

    Args:
        scenario: the scenario the campaign ran.
        results: the campaign's results (see :mod:`twin.report`).
        path: the PNG to write.

    Returns:
        The path written.
    """
    space = scenario.space
    (x0, x1), (y0, y1) = space.x_range, space.y_range
    width = min(16.0, max(6.0, 0.22 * (x1 - x0) + 2.0))
    height = min(12.0, max(3.5, width * (y1 - y0) / (x1 - x0) + 1.5))
    fig = Figure(figsize=(width, height), layout="constrained")
    ax = fig.add_subplot()
    colours = camera_colours(scenario, results)
    draw_space(ax, scenario)
    draw_cameras(ax, scenario, colours)
    _draw_tracks(ax, scenario, results)
    _draw_data_points(ax, results, colours)
    _draw_visits(ax, scenario, results, colours)
    pad = space.wall_thickness + 0.5
    ax.set_xlim(x0 - pad, x1 + pad)
    ax.set_ylim(y0 - pad, y1 + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"{scenario.name}: top view (stations numbered in the order of the visits)")
    ax.grid(True, color="0.9", lw=0.5, zorder=-1)
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncol=4, fontsize=8, frameon=False)
    return save_figure(fig, path)


# -- errors against distance -----------------------------------------------------------------
_SERIES = {"world": "tab:blue", "local": "tab:orange", "truth": "tab:green"}


def _errors_table(results: Results) -> list[dict[str, Any]]:
    """One row per calibration with a distance: the errors the figure plots."""
    rows = []
    for entry in calibrations(results):
        d = number(entry.get("distance_travelled_m"))
        if d is None:
            continue
        key = visit_key(entry)
        rows.append(
            {
                "key": key,
                "d": d,
                "world_px": error(entry, "world", "pixel_mean"),
                "world_mm": error(entry, "world", "error_3d_mean_mm"),
                "local_px": error(entry, "local", "pixel_mean"),
                "local_mm": error(entry, "local", "error_3d_mean_mm"),
                "truth_mm": number(mapping(entry.get("truth")).get("position_error_mm")),
                "paper": paper.table_iii(*key),
            }
        )
    return rows


def _series(
    ax: Axes, rows: list[dict[str, Any]], field: str, label: str, colour: str, marker: str
) -> bool:
    pts = [(r["d"], r[field]) for r in rows if r[field] is not None]
    if not pts:
        return False
    xs, ys = zip(*sorted(pts), strict=True)
    ax.plot(xs, ys, marker=marker, color=colour, lw=1.0, ms=6, label=label)
    return True


def _paper_series(
    ax: Axes, rows: list[dict[str, Any]], attr: str, label: str, colour: str, marker: str
) -> bool:
    pts = [(r["d"], getattr(r["paper"], attr)) for r in rows if r["paper"] is not None]
    if not pts:
        return False
    xs, ys = zip(*sorted(pts), strict=True)
    ax.plot(xs, ys, ls="", marker=marker, mfc="none", mec=colour, mew=1.3, ms=9, label=label)
    return True


def error_vs_distance(results: Results, path: str | Path) -> Path:
    """Table III as a plot: errors of each calibration against the distance travelled.

    Left: mean pixel error, world frame (against the reference set) and local frame (the
    calibration's own data). Right: mean 3D error, world and local, and the error of the
    calibrated camera position against the twin's truth. The paper's Table III values are
    drawn as hollow markers; the paper gives no distance per visit, so they are placed at
    this run's distance for the same (camera, visit), as the legend says.

    Args:
        results: the campaign's results.
        path: the PNG to write.

    Returns:
        The path written.
    """
    rows = _errors_table(results)
    fig = Figure(figsize=(11.0, 4.2), layout="constrained")
    ax_px, ax_mm = fig.subplots(1, 2)
    note = " (paper's values at this run's distances)"
    any_px = _series(ax_px, rows, "world_px", "twin, world", _SERIES["world"], "o")
    any_px |= _series(ax_px, rows, "local_px", "twin, local", _SERIES["local"], "s")
    any_px |= _paper_series(
        ax_px, rows, "world_pixel", "paper, world" + note, _SERIES["world"], "o"
    )
    any_px |= _paper_series(
        ax_px, rows, "local_pixel", "paper, local" + note, _SERIES["local"], "s"
    )
    any_mm = _series(ax_mm, rows, "world_mm", "twin, world", _SERIES["world"], "o")
    any_mm |= _series(ax_mm, rows, "local_mm", "twin, local", _SERIES["local"], "s")
    any_mm |= _series(
        ax_mm, rows, "truth_mm", "twin, camera position vs truth", _SERIES["truth"], "^"
    )
    any_mm |= _paper_series(
        ax_mm, rows, "world_3d_mm", "paper, world" + note, _SERIES["world"], "o"
    )
    any_mm |= _paper_series(
        ax_mm, rows, "local_3d_mm", "paper, local" + note, _SERIES["local"], "s"
    )
    for ax, any_data, ylabel, title in (
        (ax_px, any_px, "mean pixel error [px]", "Pixel error"),
        (ax_mm, any_mm, "mean error [mm]", "3D error and camera position error"),
    ):
        ax.set_xlabel("distance travelled by the parent [m]")
        ax.set_ylabel(ylabel)
        ax.set_title(title)
        ax.grid(True, color="0.9")
        if not any_data:
            no_data(ax, "no calibrations with errors and distances")
            continue
        ax.set_ylim(bottom=0.0)
        top = ax.secondary_xaxis("top")
        top.set_xticks([r["d"] for r in rows], [visit_name(r["key"]) for r in rows])
        top.tick_params(labelsize=7, labelrotation=60)
        ax.legend(fontsize=7, loc="upper left")
    return save_figure(fig, path)


# -- residuals -------------------------------------------------------------------------------
def residuals(results: Results, path: str | Path) -> Path:
    """The calibration residual vectors of each calibration, one subplot each.

    Each subplot scatters the (du, dv) residuals of one calibration, as the campaign
    stored them, with the image's v axis pointing down,
    equal scales, and the RMS of the residual length in its title.

    Args:
        results: the campaign's results.
        path: the PNG to write.

    Returns:
        The path written.
    """
    cals = calibrations(results)
    colours = camera_colours(None, results)
    n = max(1, len(cals))
    ncols = min(n, 5)
    nrows = math.ceil(n / ncols)
    fig = Figure(figsize=(2.8 * ncols + 0.6, 2.9 * nrows + 0.4), layout="constrained")
    axes = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False)).ravel()
    if not cals:
        no_data(axes[0], "no calibrations")
        axes[0].set_axis_off()
    for ax, entry in zip(axes, cals, strict=False):
        key = visit_key(entry)
        res = points_xy(entry.get("residuals_px"))
        ax.axhline(0.0, color="0.8", lw=0.6)
        ax.axvline(0.0, color="0.8", lw=0.6)
        if len(res):
            rms = float(np.sqrt(np.mean(np.sum(res**2, axis=1))))
            ax.plot(res[:, 0], res[:, 1], ls="", marker=".", ms=4, color=colours.get(key[0], "k"))
            lim = max(1.2 * float(np.max(np.abs(res))), 1e-3)
            ax.set_title(f"{visit_name(key)}: RMS {rms:.3g} px (N={len(res)})", fontsize=9)
        else:
            lim = 1.0
            ax.set_title(f"{visit_name(key)}: no residuals", fontsize=9)
            no_data(ax, "not available")
        ax.set_xlim(-lim, lim)
        ax.set_ylim(lim, -lim)
        ax.set_aspect("equal")
        ax.set_xlabel("du [px]", fontsize=8)
        ax.set_ylabel("dv [px]", fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in axes[len(cals) if cals else 1 :]:
        ax.set_axis_off()
    fig.suptitle("Calibration residuals, px", fontsize=10)
    return save_figure(fig, path)
