"""The Monte-Carlo report: ``DIR/report.md`` with the tables of ``summary.json`` and the
figures."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from twin.montecarlo.paper_targets import LOCAL_BAND, SPREAD, WORLD_BAND
from twin.montecarlo.sources import SOURCES, UNPREDICTED
from twin.montecarlo.summary import AGREEMENT
from twin.outputs import write_text_atomic
from twin.report.formatting import fmt, table
from twin.report.reading import visit_name


def _distribution_rows(summary: dict[str, Any]) -> list[str]:
    rows = []
    for v in summary["visits"]:
        p, r = v["position_error_mm"], v["rotation_error_deg"]
        rows.append(
            [
                visit_name((v["camera"], v["visit"])),
                fmt(v["distance_travelled_m"]["median"], ".1f"),
                f"{100 * v['calibrated_fraction']:.0f} %",
                fmt(p["median"], ".1f"),
                fmt(p["p90"], ".1f"),
                fmt(p["p99"], ".1f"),
                fmt(r["median"], ".3f"),
                fmt(r["p90"], ".3f"),
                fmt(r["p99"], ".3f"),
            ]
        )
    return table(
        [
            "visit",
            "travel [m]",
            "calibrated",
            "pos. median [mm]",
            "pos. 90 %",
            "pos. 99 %",
            "rot. median [deg]",
            "rot. 90 %",
            "rot. 99 %",
        ],
        rows,
    )


def _failures(summary: dict[str, Any]) -> list[str]:
    """The failures section: the visits not calibrated by reason, the failures by kind."""
    failures = summary.get("failures")
    if not failures or not (failures["kinds"] or failures["not_calibrated"]):
        return []
    lines = ["", "## Failures (all sources)", ""]
    if failures["not_calibrated"]:
        lines.append("Visits not calibrated, by reason:")
        lines.append("")
        lines += table(
            ["reason", "visits"], [[k, str(n)] for k, n in failures["not_calibrated"].items()]
        )
        lines.append("")
    if failures["kinds"]:
        lines.append(
            f"Failures by kind, over {failures['trials_with_failures']} trials that had any:"
        )
        lines.append("")
        lines += table(["kind", "count"], [[k, str(n)] for k, n in failures["kinds"].items()])
    return lines


def _table_iii_rows(summary: dict[str, Any]) -> list[str]:
    rows = [
        [
            visit_name((v["camera"], v["visit"])),
            *(
                f"{fmt(v[m]['median'])} / {fmt(v[m]['p90'])}"
                for m in (
                    "world_pixel_mean",
                    "world_error_3d_mean_mm",
                    "local_pixel_mean",
                    "local_error_3d_mean_mm",
                )
            ),
        ]
        for v in summary["visits"]
    ]
    return table(["visit", "world px", "world 3D [mm]", "local px", "local 3D [mm]"], rows)


def _prediction(summary: dict[str, Any]) -> list[str]:
    rows, notes = [], []
    left_out = summary.get("unpredicted_sources") or []
    too_small = (
        "The prediction leaves out what this scenario adds and the campaign does not model: "
        + "; ".join(f"{s.replace('_', ' ')} ({UNPREDICTED[s]})" for s in left_out)
        + "."
        if left_out
        else "Tsai's covariance treats the data points as independent, but the four "
        "LEDs of one stop share the error of the marker pose measured by the "
        "total station, so the calibration's own part is underestimated."
    )
    for v in summary["visits"]:
        pr = v["predicted"]
        name = visit_name((v["camera"], v["visit"]))
        rows.append(
            [
                name,
                fmt(v["position_error_mm"]["rms"], ".1f"),
                fmt(pr["transfer_rms_mm"], ".1f"),
                fmt(pr["calibration_rms_mm"], ".1f"),
                fmt(pr["rms_mm"], ".1f"),
                fmt(pr["mc_over_predicted"]),
                "yes" if pr["agrees"] else "**no**",
            ]
        )
        ratio = pr["mc_over_predicted"]
        if math.isfinite(ratio) and not pr["agrees"]:
            notes.append(
                f"- {name}: the Monte-Carlo RMS is {ratio:.2f} times the prediction. "
                + (
                    too_small
                    if ratio > 1
                    else "The prediction is pessimistic here (Tsai's covariance is scaled by "
                    "residuals that include the 3D points' noise)."
                )
            )
    out = table(
        [
            "visit",
            "MC RMS [mm]",
            "transfer [mm]",
            "calibration [mm]",
            "predicted RMS [mm]",
            "MC / predicted",
            "agrees",
        ],
        rows,
    )
    parent = summary["parent_final"]
    if "x" in parent:
        out += [
            "",
            f"The parent's final position after {fmt(parent['distance_travelled_m'], '.1f')} m:",
            "",
        ]
        out += table(
            ["axis", "MC std [mm]", "MC mean [mm]", "predicted std [mm]", "MC / predicted"],
            [
                [
                    a,
                    fmt(parent[a]["mc_std_mm"]),
                    fmt(parent[a]["mc_mean_mm"]),
                    fmt(parent[a]["predicted_std_mm"]),
                    fmt(parent[a]["mc_over_predicted"]),
                ]
                for a in "xyz"
            ],
        )
    lo, hi = AGREEMENT
    return [
        f"Agreement: Monte-Carlo RMS / predicted RMS within {lo}-{hi}. The prediction adds "
        "the frame transfer (the parent's pose covariance at the station, propagated to the "
        "camera's centre) and the calibration's own covariance (Tsai).",
        "",
        *out,
        *(["", *notes] if notes else []),
    ]


def _adjusted(summary: dict[str, Any]) -> list[str]:
    """The global adjustment's errors beside the sequential ones, where the trials hold
    them."""
    visits = [v for v in summary["visits"] if "adjusted" in v]
    if not visits:
        return []
    rows = []
    for v in visits:
        a = v["adjusted"]
        seq, adj = v["position_error_mm"], a["position_error_mm"]
        rows.append(
            [
                visit_name((v["camera"], v["visit"])),
                fmt(seq["median"], ".1f"),
                fmt(adj["median"], ".1f"),
                fmt(seq["rms"], ".1f"),
                fmt(adj["rms"], ".1f"),
                fmt(adj["rms"] / seq["rms"] if seq["rms"] else math.nan),
                fmt(a["predicted_rms_mm"], ".1f"),
                fmt(a["mc_over_predicted"]),
            ]
        )
    return [
        "",
        "## Global adjustment",
        "",
        "The camera position error of the sequential calibrations (the paper's) and of the "
        "global adjustment of each trial (every measurement at once), and the adjustment's "
        "own predicted RMS (from its covariance) against its Monte-Carlo RMS.",
        "",
        *table(
            [
                "visit",
                "sequential median [mm]",
                "adjusted median [mm]",
                "sequential RMS [mm]",
                "adjusted RMS [mm]",
                "adjusted / sequential",
                "adjusted predicted RMS [mm]",
                "MC / predicted",
            ],
            rows,
        ),
    ]


def _paper(summary: dict[str, Any]) -> list[str]:
    """The paper's Table III and repeatability beside the twin's distribution."""
    entries = summary.get("paper")
    if not entries:
        return []
    rows = [
        [
            e["name"],
            fmt(e["paper"]),
            fmt(e["median"]),
            f"{fmt(e['p10'])} - {fmt(e['p90'])}",
            fmt(e["paper_percentile"], ".0f"),
            fmt(e["ratio"]),
            "yes" if e["matched"] else "no",
        ]
        for e in entries
    ]
    n = sum(e["matched"] for e in entries)
    return [
        "",
        "## Against the paper (Table III and the repeatability)",
        "",
        f"The paper's value beside the twin's median and {SPREAD[0]:.0f}-{SPREAD[1]:.0f} % "
        "range over the trials, and where the paper's value falls among them (its "
        "percentile). Matched: a local entry's median within "
        f"{100 * LOCAL_BAND:.0f} % of the paper's, a world entry's within "
        f"{100 * WORLD_BAND:.0f} %, the paper's repeatability inside the twin's "
        f"{SPREAD[0]:.0f}-{SPREAD[1]:.0f} % range. {n} of {len(entries)} matched.",
        "",
        *table(
            [
                "entry",
                "paper",
                "twin median",
                f"twin {SPREAD[0]:.0f}-{SPREAD[1]:.0f} %",
                "paper's percentile",
                "median / paper",
                "matched",
            ],
            rows,
        ),
    ]


def _budget(summary: dict[str, Any]) -> list[str]:
    b = summary.get("budget")
    if not b:
        return ["No one-source runs in this table: run `twin montecarlo` with the budget on."]
    entries = [*b["visits"], {"camera": "all visits", "visit": 0, **b["overall"]}]
    rows = []
    for e in entries:
        name = e["camera"] if e["visit"] == 0 else visit_name((e["camera"], e["visit"]))
        rows.append(
            [
                name,
                fmt(e["all_rms_mm"], ".1f"),
                *(
                    f"{fmt(e['rms_mm'][s], '.1f')} ({fmt(100 * e['share'][s], '.0f')} %)"
                    for s in b["sources"]
                ),
                fmt(e["sum_over_all"]),
            ]
        )
    top = max(b["sources"], key=lambda s: b["overall"]["share"][s])
    return [
        "RMS position error with each source alone, and its share of the sum of mean "
        "squares. `sum / all` near 1 means the sources add up independently.",
        "",
        *table(
            ["visit", "all [mm]", *(s.replace("_", " ") for s in b["sources"]), "sum / all"],
            rows,
        ),
        "",
        f"The largest source over all visits: **{top.replace('_', ' ')}** "
        f"({100 * b['overall']['share'][top]:.0f} % of the mean square): {SOURCES[top]}.",
    ]


def render_report(summary: dict[str, Any], figures: Mapping[str, Path], out_dir: Path) -> str:
    """The report's Markdown."""
    rate = summary.get("trials_per_second")
    lines = [
        f"# Monte-Carlo error budget: {summary['scenario']}",
        "",
        f"- fidelity: {summary['fidelity']}; master seed {summary['master_seed']}; "
        f"{summary['trials_done']} trials per configuration "
        f"({', '.join(summary['configurations'])})",
        f"- scenario file: `{summary.get('scenario_file') or '-'}`",
    ]
    if rate:
        lines.append(f"- {rate:.2f} trials per second in the last session")
    lines += ["", "## World-frame camera error per visit (all sources)", ""]
    lines += _distribution_rows(summary)
    lines += _failures(summary)
    lines += ["", "## Table III metrics (median / 90 %)", "", *_table_iii_rows(summary)]
    lines += _paper(summary)
    lines += _adjusted(summary)
    lines += ["", "## Monte Carlo against the covariance propagation", "", *_prediction(summary)]
    lines += ["", "## Error budget", "", *_budget(summary), "", "## Figures", ""]
    for name, path in figures.items():
        lines.append(f"![{name.replace('_', ' ')}]({path.relative_to(out_dir).as_posix()})")
        lines.append("")
    return "\n".join(lines)


def write_report(summary: dict[str, Any], figures: Mapping[str, Path], out_dir: str | Path) -> Path:
    """Write ``out_dir/report.md``; returns its path."""
    out = Path(out_dir)
    path = out / "report.md"
    write_text_atomic(path, render_report(summary, figures, out))
    return path
