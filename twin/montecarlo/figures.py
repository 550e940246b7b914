"""Figures of a Monte-Carlo run: error histograms, error against distance, the budget, and
the twin against the paper's measurements.

Drawn on Agg figures without pyplot, as :mod:`twin.report.figures`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle
from matplotlib.ticker import NullFormatter

from twin.montecarlo.paper_targets import TARGETS, trial_values
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


def paper_percentiles(
    rows: Sequence[dict[str, Any]], summary: dict[str, Any], path: str | Path
) -> Path:
    """For each of the paper's numbers (Table III, repeatability), the twin's distribution
    over trials divided by the paper's value (log scale), with the paper at 1 and its
    percentile among the trials written beside it."""
    entries = summary["paper"]
    fig = Figure(figsize=(8.0, 0.32 * len(entries) + 1.4))
    ax = fig.add_subplot()
    data, labels = [], []
    for e in entries:
        target = next(t for t in TARGETS if t.name == e["name"])
        values = trial_values(rows, target)
        data.append(values / target.paper if len(values) else np.array([np.nan]))
        labels.append(e["name"])
    positions = np.arange(len(entries))[::-1]
    for y, ratios in zip(positions, data, strict=True):
        finite = ratios[np.isfinite(ratios)]
        if len(finite) == 0:
            continue
        p10, q1, med, q3, p90 = np.percentile(finite, [10, 25, 50, 75, 90])
        ax.hlines(y, p10, p90, color="0.4", lw=1.0)
        ax.add_patch(
            Rectangle((q1, y - 0.3), q3 - q1, 0.6, facecolor="tab:blue", alpha=0.25, ec="0.4")
        )
        ax.vlines(med, y - 0.3, y + 0.3, color="tab:blue", lw=1.6)
    ax.axvline(1.0, color="tab:red", lw=1.2, label="the paper's value")
    for y, e in zip(positions, entries, strict=True):
        pct = e["paper_percentile"]
        text = "—" if not math.isfinite(pct) else f"paper at {pct:.0f} %"
        ax.text(1.02, y, text, transform=ax.get_yaxis_transform(), va="center", fontsize=7)
    ax.set_yticks(positions, labels, fontsize=7)
    ax.set_ylim(-0.8, len(entries) - 0.2)
    ax.set_xscale("log")
    ticks = [0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0]
    ax.set_xticks(ticks, [f"{t:g}" for t in ticks])
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("twin / paper (box: quartiles, whiskers: 10-90 %)")
    ax.set_title(
        "The twin's distribution over trials against the paper's measurements", fontsize=10
    )
    ax.legend(fontsize=7, loc="lower left")
    fig.subplots_adjust(right=0.83)
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
        **(
            {"paper": paper_percentiles(rows, summary, folder / "paper_percentiles.png")}
            if summary.get("paper")
            else {}
        ),
    }
