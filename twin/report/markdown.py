"""The report of a campaign: a Markdown page beside the paper's Tables II and III.

:func:`write_report` writes ``report.md`` and its three figures. The page holds the run's
settings, a summary (what was calibrated, what was skipped and why, failures and the
campaign's recoveries, the parent's final error), Table II and Table III side by side with
the paper's values (paper | twin, in the paper's units: px, mm, deg), the repeatability of
cameras visited twice, the errors against the twin's truth (which the paper could not
know), the time spent by stage and the figures. The sections beside the paper are
:mod:`twin.report.comparison`'s; the tables' Markdown, :mod:`twin.report.formatting`'s.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from twin.outputs import write_text_atomic
from twin.report import figures
from twin.report.comparison import repeatability_section, table_ii_section, table_iii_section
from twin.report.formatting import NA, duration, fmt, table
from twin.report.reading import (
    Results,
    calibrations,
    entries,
    mapping,
    number,
    skipped_visits,
    vector,
    visit_key,
    visit_name,
)
from twin.scenario.schema import Scenario


# -- sections --------------------------------------------------------------------------------
def _header(scenario: Scenario | None, results: Results) -> list[str]:
    name = results.get("scenario") or (scenario.name if scenario else "unknown scenario")
    source = results.get("scenario_file") or (scenario.source if scenario else "")
    complete = results.get("complete")
    rows = [
        ("scenario", f"{name} (`{source}`)" if source else name),
        ("fidelity", results.get("fidelity", NA)),
        ("seed", results.get("seed", scenario.seed if scenario else NA)),
        ("wall time", duration(number(results.get("wall_time_s")))),
        (
            "complete",
            NA if complete is None else ("yes" if complete else "no: a partial run"),
        ),
    ]
    lines = [f"# Campaign report: {name}", ""]
    if scenario is not None and scenario.description:
        lines += [scenario.description, ""]
    lines += table(("run", "value"), rows)
    if scenario is not None and results.get("scenario") not in (None, scenario.name):
        lines += [
            "",
            f"Note: the results name scenario {results.get('scenario')!r}; "
            f"the figures draw {scenario.name!r}.",
        ]
    return [*lines, ""]


def _summary(scenario: Scenario | None, results: Results) -> list[str]:
    cals = calibrations(results)
    skipped = skipped_visits(results)
    planned = len(scenario.calibration.visits) if scenario is not None else None
    lines = ["## Summary", ""]
    if not cals:
        lines += ["**Nothing was calibrated**: no visit of this run produced a calibration.", ""]
    of = f" of {planned} planned" if planned is not None else ""
    names = ", ".join(visit_name(visit_key(e)) for e in cals) or "none"
    lines.append(f"- Calibrated visits: {len(cals)}{of} ({names}).")
    lines.append(f"- Skipped visits: {len(skipped)}.")
    final = number(results.get("parent_final_error_mm"))
    lines.append(
        "- Parent's final position error: "
        + (f"{final:.1f} mm." if final is not None else "not available.")
    )
    refs = entries(results, "reference_sets")
    if refs:
        sets = ", ".join(
            f"{r.get('camera', '?')} ({fmt(r.get('points'), '.0f')} points)" for r in refs
        )
        lines.append(f"- Reference sets (world-frame evaluation): {sets}.")
    else:
        lines.append("- Reference sets: none recorded (no world-frame errors).")
    lines.append("")
    if skipped:
        lines += ["### Skipped visits", ""]
        lines += table(
            ("visit", "station [m]", "reason", "message"),
            (
                (
                    visit_name(visit_key(s)),
                    _xy(s.get("station")),
                    s.get("reason", NA),
                    s.get("message", "") or NA,
                )
                for s in skipped
            ),
        )
        lines.append("")
    for key, title in (("failures", "Failures by kind"), ("events", "Recoveries by kind")):
        counts = mapping(results.get(key))
        lines += [f"### {title}", ""]
        if counts:
            total = sum(int(number(v) or 0) for v in counts.values())
            rows = [(k, fmt(v, ".0f")) for k, v in sorted(counts.items())]
            lines += table(("kind", "count"), [*rows, ("total", str(total))])
        else:
            lines.append("None recorded.")
        lines.append("")
    return lines


def _xy(value: Any) -> str:
    xy = vector(value, 2)
    return NA if xy is None else f"({xy[0]:.2f}, {xy[1]:.2f})"


def _truth(results: Results) -> list[str]:
    cals = calibrations(results)
    lines = [
        "## Errors against the twin's truth",
        "",
        "The twin knows each camera's true pose; the paper could not. Position error: "
        "distance between the calibrated and the true optical centre; rotation error: "
        "angle of the rotation between the calibrated and the true orientation.",
        "",
    ]
    if not cals:
        return [*lines, "No calibrations.", ""]
    rows = []
    for e in cals:
        truth = mapping(e.get("truth"))
        rows.append(
            (
                visit_name(visit_key(e)),
                fmt(e.get("distance_travelled_m"), ".1f"),
                fmt(e.get("points"), ".0f"),
                fmt(truth.get("position_error_mm"), ".1f"),
                fmt(truth.get("rotation_error_deg"), ".3f"),
            )
        )
    lines += table(
        ("visit", "distance [m]", "points", "position error [mm]", "rotation error [deg]"), rows
    )
    return [*lines, ""]


def _adjustment(results: Results) -> list[str]:
    info = mapping(results.get("adjustment"))
    if not info:
        return []
    lines = ["## Global adjustment: every measurement at once", ""]
    if info.get("status") != "adjusted":
        return [*lines, str(info.get("message", "")), ""]
    lines += [
        "CPS fixes each station from the last; the adjustment solves every station, every "
        "child stand, every camera and every control point from all the total station's "
        "shots and all the LED pixels together, with their stated noise as weights. What "
        "it could use beyond the chain of CPS steps: "
        + "; ".join(str(r) for r in info.get("redundancy", []))
        + f". Cameras: {info.get('cameras')}. Chi-square per degree of freedom "
        f"{fmt(info.get('variance_factor'))} (about 1 when the stated noise is right).",
        "",
    ]
    if info.get("consistent") is False:
        lines[-1:-1] = [
            "",
            f"**The global test fails**: chi-square {fmt(info.get('chi2'))} over "
            f"{info.get('dof')} degrees of freedom is more than the stated noise allows. An "
            "error the weights leave out is in the data (a marker surveyed worse than stated, "
            "a station that moved); the adjusted standard deviations below are scaled by "
            f"chi-square per degree of freedom ({fmt(info.get('covariance_scale'))}).",
        ]
    rows = []
    adjusted = {
        visit_key(e): e
        for e in calibrations({"calibrations": results.get("adjusted_calibrations", [])})
    }
    for e in calibrations(results):
        key = visit_key(e)
        a = adjusted.get(key, {})
        world = mapping(mapping(e.get("errors")).get("world"))
        world_a = mapping(mapping(a.get("errors")).get("world"))
        truth, truth_a = mapping(e.get("truth")), mapping(a.get("truth"))
        std = mapping(a.get("std"))
        sigma = [number(std.get(k)) for k in ("x", "y", "z")]
        rms = (
            1e3 * math.sqrt(sum(v * v for v in sigma))
            if all(v is not None for v in sigma)
            else None
        )
        rows.append(
            (
                visit_name(key),
                fmt(world.get("error_3d_mean_mm")),
                fmt(world_a.get("error_3d_mean_mm")),
                fmt(truth.get("position_error_mm"), ".1f"),
                fmt(truth_a.get("position_error_mm"), ".1f"),
                fmt(rms, ".1f"),
            )
        )
    lines += table(
        (
            "visit",
            "world 3D [mm]",
            "adjusted",
            "position error [mm]",
            "adjusted",
            "adjusted predicted [mm]",
        ),
        rows,
    )
    return [*lines, "", *_marker_survey(info)]


def _marker_survey(info: Mapping[str, Any]) -> list[str]:
    """The children's adjusted marker surveys: each LED's offset from the drawing."""
    survey = mapping(info.get("marker_survey"))
    if not survey:
        return []
    if "message" in survey:
        return [f"Marker survey: {survey['message']}.", ""]
    lines = [
        "Each child's marker assembly is known only to its survey: the adjustment solved "
        "where its LEDs stand off the drawing, in the frame its cubes (as drawn) define "
        "(mm, +/- one standard deviation).",
        "",
    ]
    rows = []
    for child, entry in survey.items():
        offsets = mapping(entry).get("leds_offset_mm", [])
        stds = mapping(entry).get("leds_offset_std_mm", [])
        for k, (offset, std) in enumerate(zip(offsets, stds, strict=True)):
            cells = (
                f"{fmt(v, '.1f')} +/- {fmt(e, '.1f')}" for v, e in zip(offset, std, strict=True)
            )
            rows.append((str(child), str(k), *cells))
    lines += table(("child", "LED", "x", "y", "z"), rows)
    return [*lines, ""]


def _timings(results: Results) -> list[str]:
    timings = {str(k): number(v) for k, v in mapping(results.get("timings_s")).items()}
    timings = {k: v for k, v in timings.items() if v is not None}
    if not timings:
        return []
    total = sum(timings.values())
    rows = [
        (k, f"{v:.1f}", f"{100.0 * v / total:.0f} %" if total > 0 else NA)
        for k, v in timings.items()
    ]
    rows.append(("total", f"{total:.1f}", "100 %" if total > 0 else NA))
    return ["## Time by stage", "", *table(("stage", "time [s]", "share"), rows), ""]


def _figures(paths: Mapping[str, Path], out_dir: Path) -> list[str]:
    titles = {
        "top_view": "Top view: hall, cameras' floor views, route, track, stations, child data",
        "error_vs_distance": "Errors against the distance travelled (Table III as a plot)",
        "residuals": "Calibration residuals",
    }
    lines = ["## Figures", ""]
    for name, path in paths.items():
        rel = path.relative_to(out_dir).as_posix()
        lines += [f"### {titles.get(name, name)}", "", f"![{titles.get(name, name)}]({rel})", ""]
    return lines


# -- the report ------------------------------------------------------------------------------
def render_markdown(
    scenario: Scenario | None, results: Results, figure_paths: Mapping[str, Path], out_dir: Path
) -> str:
    """The report's Markdown text (figures already written under ``out_dir``)."""
    lines: list[str] = []
    lines += _header(scenario, results)
    lines += _summary(scenario, results)
    lines += table_ii_section(scenario, results)
    lines += table_iii_section(scenario, results)
    lines += repeatability_section(results)
    lines += _truth(results)
    lines += _adjustment(results)
    lines += _timings(results)
    lines += _figures(figure_paths, out_dir)
    text = "\n".join(lines).rstrip() + "\n"
    return text


def write_report(scenario: Scenario, results: Results, out_dir: str | Path) -> Path:
    """Write a campaign's report: ``out_dir/report.md`` and ``out_dir/figures/*.png``.

    Args:
        scenario: the scenario the campaign ran (for the hall, cameras, route, visits).
        results: the campaign's results (the content of ``results.json``); any field may
            be missing.
        out_dir: the folder to write to (created if needed).

    Returns:
        The path of ``report.md``.
    """
    out_dir = Path(out_dir)
    fig_dir = out_dir / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    paths = {
        "top_view": figures.top_view(scenario, results, fig_dir / "top_view.png"),
        "error_vs_distance": figures.error_vs_distance(results, fig_dir / "error_vs_distance.png"),
        "residuals": figures.residuals(results, fig_dir / "residuals.png"),
    }
    report = out_dir / "report.md"
    write_text_atomic(report, render_markdown(scenario, results, paths, out_dir))
    return report
