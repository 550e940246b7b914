"""Figures of a Monte-Carlo run: error histograms, error against distance, the budget.

Drawn on Agg figures without pyplot, as :mod:`twin.report.figures`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from twin.montecarlo.sources import ALL
from twin.montecarlo.summary import visits_of
from twin.report.figures import PALETTE, no_data, save_figure
from twin.report.reading import visit_name


def histograms(rows: Sequence[dict[str, Any]], summary: dict[str, Any], path: str | Path) -> Path:
    """One histogram of the world-frame camera position error per visit (all sources),
    with the median, the 90th percentile and the predicted RMS marked."""
    visits = visits_of(rows)
    n = max(len(visits), 1)
    cols = min(n, 3)
    fig = Figure(figsize=(4.2 * cols, 3.2 * math.ceil(n / cols)))
    by_visit = {(v["camera"], v["visit"]): v for v in summary["visits"]}
    for i, key in enumerate(visits or [("-", 0)]):
        ax = fig.add_subplot(math.ceil(n / cols), cols, i + 1)
        err = [
            r["position_error_mm"]
            for r in rows
            if r["config"] == ALL and (r["camera"], r["visit"]) == key and r["calibrated"]
        ]
        if not err:
            no_data(ax, "no calibration")
            continue
        ax.hist(err, bins=min(40, max(8, len(err) // 5)), color=PALETTE[0], alpha=0.8)
        s = by_visit[key]
        d = s["position_error_mm"]
        ax.axvline(d["median"], color="k", lw=1.2, label=f"median {d['median']:.1f} mm")
        ax.axvline(d["p90"], color="k", ls="--", lw=1, label=f"90 % {d['p90']:.1f} mm")
        pred = s["predicted"]["rms_mm"]
        if math.isfinite(pred):
            ax.axvline(pred, color=PALETTE[2], lw=1.2, label=f"predicted RMS {pred:.1f} mm")
        travel = s["distance_travelled_m"]["median"]
        ax.set_title(f"{visit_name(key)}, {travel:.0f} m travelled", fontsize=9)
        ax.set_xlabel("camera position error [mm]")
        ax.set_ylabel("trials")
        ax.legend(fontsize=7)
    fig.suptitle("World-frame camera position error over the trials", fontsize=10)
    return save_figure(fig, path)


def error_vs_distance(summary: dict[str, Any], path: str | Path) -> Path:
    """Median and 90th percentile of the camera position error against the parent's
    travel, with the predicted RMS and the parent's own final error."""
    fig = Figure(figsize=(7.0, 4.2))
    ax = fig.add_subplot(1, 1, 1)
    vs = [v for v in summary["visits"] if v["position_error_mm"]["n"]]
    if not vs:
        no_data(ax, "no calibration")
        return save_figure(fig, path)
    x = np.array([v["distance_travelled_m"]["median"] for v in vs])
    med = np.array([v["position_error_mm"]["median"] for v in vs])
    p90 = np.array([v["position_error_mm"]["p90"] for v in vs])
    rms = np.array([v["position_error_mm"]["rms"] for v in vs])
    pred = np.array([v["predicted"]["rms_mm"] for v in vs])
    ax.vlines(x, med, p90, color=PALETTE[0], lw=2, alpha=0.5, label="median to 90 %")
    ax.plot(x, med, "o", color=PALETTE[0], label="median")
    ax.plot(x, rms, "s", mfc="none", color="k", label="Monte-Carlo RMS")
    ax.plot(x, pred, "x", color=PALETTE[2], ms=9, mew=2, label="predicted RMS")
    for xi, yi, v in zip(x, p90, vs, strict=True):
        ax.annotate(
            visit_name((v["camera"], v["visit"])),
            (xi, yi),
            fontsize=7,
            textcoords="offset points",
            xytext=(3, 4),
        )
    parent = summary.get("parent_final", {})
    if "rms_3d" in parent:
        ax.plot(
            [parent["distance_travelled_m"]],
            [parent["rms_3d"]["mc_mm"]],
            "D",
            color=PALETTE[4],
            label="parent's final position (RMS)",
        )
    ax.set_xlabel("distance travelled by the parent [m]")
    ax.set_ylabel("world-frame position error [mm]")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Camera position error against distance travelled", fontsize=10)
    return save_figure(fig, path)


def budget_bars(budget: dict[str, Any] | None, path: str | Path) -> Path:
    """Each noise source's share of the mean squared camera position error, per visit and
    over all visits (stacked bars)."""
    fig = Figure(figsize=(8.0, 4.2))
    ax = fig.add_subplot(1, 1, 1)
    if not budget:
        no_data(ax, "no one-source runs (run with the budget)")
        return save_figure(fig, path)
    entries = [*budget["visits"], {"camera": "all visits", "visit": 0, **budget["overall"]}]
    labels = [
        e["camera"] if e["visit"] == 0 else visit_name((e["camera"], e["visit"])) for e in entries
    ]
    bottom = np.zeros(len(entries))
    for i, source in enumerate(budget["sources"]):
        share = np.array([e["share"][source] for e in entries], dtype=float)
        share = np.nan_to_num(share)
        ax.bar(
            labels,
            100 * share,
            bottom=100 * bottom,
            color=PALETTE[i % len(PALETTE)],
            label=source.replace("_", " "),
        )
        bottom += share
    ax.set_ylabel("share of the mean squared position error [%]")
    ax.set_ylim(0, 100)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    ax.set_title("Error budget: where the world-frame camera error comes from", fontsize=10)
    ax.tick_params(axis="x", labelsize=8, rotation=20)
    return save_figure(fig, path)


def write_figures(
    rows: Sequence[dict[str, Any]], summary: dict[str, Any], folder: str | Path
) -> dict[str, Path]:
    """All the figures in ``folder``, by name."""
    folder = Path(folder)
    return {
        "histograms": histograms(rows, summary, folder / "position_error_histograms.png"),
        "error_vs_distance": error_vs_distance(summary, folder / "error_vs_distance.png"),
        "budget": budget_bars(summary.get("budget"), folder / "budget.png"),
    }
