"""The report of a campaign: a Markdown page beside the paper's Tables II and III.

:func:`write_report` writes ``report.md`` and its three figures. The page holds the run's
settings, a summary (what was calibrated, what was skipped and why, failures and the
campaign's recoveries, the parent's final error), Table II and Table III side by side with
the paper's values (paper | twin, in the paper's units: px, mm, deg), the repeatability of
cameras visited twice, the errors against the twin's truth (which the paper could not
know), the time spent by stage and the figures.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from twin.outputs import write_text_atomic
from twin.report import figures, paper
from twin.report.reading import (
    Results,
    VisitKey,
    calibrations,
    entries,
    error,
    mapping,
    number,
    planned_visits,
    skipped_visits,
    vector,
    visit_key,
    visit_name,
)
from twin.scenario.schema import Scenario

NA = "—"
"""What a table cell shows when a value is not available."""


# -- formatting ------------------------------------------------------------------------------
def fmt(value: Any, spec: str = ".2f") -> str:
    """A number with ``spec`` (format specification), or ``—`` if it is not a number."""
    x = number(value)
    return NA if x is None else format(x, spec)


def cell(text: Any) -> str:
    """Text safe inside a Markdown table cell (no pipes, no line breaks)."""
    return " ".join(str(text).split()).replace("|", "\\|") or " "


def table(header: Sequence[str], rows: Iterable[Sequence[Any]]) -> list[str]:
    """A Markdown table; every row is padded or cut to the header's number of cells.

    Args:
        header: the column headings.
        rows: the rows, each a sequence of cell values (converted with ``str``).

    Returns:
        The table's lines.
    """
    n = len(header)
    lines = ["| " + " | ".join(cell(h) for h in header) + " |", "|" + "---|" * n]
    for row in rows:
        cells = [cell(c) for c in list(row)[:n]]
        cells += [" "] * (n - len(cells))
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _duration(seconds: float | None) -> str:
    if seconds is None:
        return NA
    if seconds < 60:
        return f"{seconds:.1f} s"
    minutes, rest = divmod(seconds, 60.0)
    if minutes < 60:
        return f"{seconds:.1f} s ({int(minutes)} min {rest:.0f} s)"
    hours, minutes = divmod(minutes, 60.0)
    return f"{seconds:.0f} s ({int(hours)} h {int(minutes)} min)"


# -- columns ---------------------------------------------------------------------------------
def _columns(
    scenario: Scenario | None, results: Results, paper_keys: Iterable[VisitKey]
) -> list[VisitKey]:
    """The visits to show: the scenario's in order, then other calibrated or skipped visits,
    then the paper's visits the run does not have."""
    keys: list[VisitKey] = [k for k, _ in planned_visits(scenario)] if scenario else []
    for entry in calibrations(results) + skipped_visits(results):
        key = visit_key(entry)
        if key not in keys:
            keys.append(key)
    for key in paper_keys:
        if key not in keys:
            keys.append(key)
    return keys


def _by_key(items: Iterable[Mapping[str, Any]]) -> dict[VisitKey, Mapping[str, Any]]:
    out: dict[VisitKey, Mapping[str, Any]] = {}
    for entry in items:
        out.setdefault(visit_key(entry), entry)
    return out


# -- sections --------------------------------------------------------------------------------
def _header(scenario: Scenario | None, results: Results) -> list[str]:
    name = results.get("scenario") or (scenario.name if scenario else "unknown scenario")
    source = results.get("scenario_file") or (scenario.source if scenario else "")
    complete = results.get("complete")
    rows = [
        ("scenario", f"{name} (`{source}`)" if source else name),
        ("fidelity", results.get("fidelity", NA)),
        ("seed", results.get("seed", scenario.seed if scenario else NA)),
        ("wall time", _duration(number(results.get("wall_time_s")))),
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


_PARAMETERS: tuple[tuple[str, Callable[[paper.PaperCalibration], Any], str, str], ...] = (
    ("f / pixel size [px]", lambda p: p.f_px, "f_px", ".1f"),
    ("image centre x [px]", lambda p: p.cx, "cx", ".1f"),
    ("image centre y [px]", lambda p: p.cy, "cy", ".1f"),
    ("kappa1 (paper's number; twin: 1/px²) ¹", lambda p: p.kappa1, "kappa1_px", ".3g"),
)


def _table_ii(scenario: Scenario | None, results: Results) -> list[str]:
    keys = _columns(scenario, results, (c.key for c in paper.TABLE_II))
    done = _by_key(calibrations(results))
    skipped = _by_key(skipped_visits(results))
    header = ["parameter"]
    for key in keys:
        header += [f"{visit_name(key)} paper", f"{visit_name(key)} twin"]

    def twin(key: VisitKey, get: Callable[[Mapping[str, Any]], Any], spec: str) -> str:
        if key not in done:
            return "skipped" if key in skipped else NA
        return fmt(get(mapping(done[key].get("parameters"))), spec)

    def row(
        label: str,
        from_paper: Callable[[paper.PaperCalibration], Any] | None,
        from_twin: Callable[[Mapping[str, Any]], Any],
        spec_paper: str,
        spec_twin: str,
    ) -> list[str]:
        out = [label]
        for key in keys:
            col = paper.table_ii(*key)
            out.append(fmt(from_paper(col), spec_paper) if col and from_paper else NA)
            out.append(twin(key, from_twin, spec_twin))
        return out

    def component(field: str, i: int, n: int) -> Callable[[Mapping[str, Any]], Any]:
        def get(params: Mapping[str, Any]) -> Any:
            v = vector(params.get(field), n)
            return None if v is None else v[i]

        return get

    rows = [
        row(label, get, lambda q, f=field: q.get(f), spec, spec)
        for label, get, field, spec in _PARAMETERS
    ]
    rows.append(
        row(
            "kappa1 [1/mm²] at the run's pixel pitch",
            None,
            lambda q: q.get("kappa1_per_mm2"),
            "",
            ".3g",
        )
    )
    rows.append(row("scale factor sx", None, lambda q: q.get("sx"), "", ".5f"))
    for i, axis in enumerate("XYZ"):
        rows.append(
            row(
                f"position {axis} [mm]",
                lambda p, i=i: p.position_mm[i],
                component("position_mm", i, 3),
                ".1f",
                ".1f",
            )
        )
    for i, axis in enumerate("XYZ"):
        rows.append(
            row(
                f"rotation about {axis} [deg] ²",
                lambda p, i=i: p.rotation_deg[i],
                component("rotation_deg", i, 3),
                ".1f",
                ".2f",
            )
        )
    lines = ["## Table II: calibrated parameters (paper | twin)", ""]
    lines += table(header, rows)
    lines += [
        "",
        "¹ The paper labels kappa1 in 1/mm²; read so, with any plausible pixel pitch, it "
        "would bend the image by less than a thousandth of a pixel. This project reads the "
        "paper's numbers in 1/px² (see `scenarios/paper_hall.toml`), so the twin's kappa1 in "
        "1/px² stands beside them; the next row gives the twin's value in 1/mm² at the pixel "
        "pitch the campaign chose.",
        "",
        "² Tsai's angles of the world-to-camera rotation about X, Y, Z. The twin's scenario "
        "takes the cameras' positions and optical axes from Table II, but flips the sign of "
        "the X angles of cameras 1 and 2 (a sign lost in the table) and keeps each image "
        "upright where the paper's images are rolled by 3-8 deg (see "
        "`scenarios/paper_hall.toml`). The twin's X angles of cameras 1 and 2 therefore "
        "differ in sign from the paper's and its Z angles by a few degrees (or by a wrap "
        "of 360 deg near ±180 deg).",
        "",
        "Positions are in the world frame W (the parent's instrument frame at its first "
        "station), as in the paper. " + NA + ": not available; skipped: the run skipped "
        "that visit (see the summary).",
        "",
    ]
    return lines


def _table_iii(scenario: Scenario | None, results: Results) -> list[str]:
    done = _by_key(calibrations(results))
    skipped = _by_key(skipped_visits(results))
    paper_keys = [c.key for c in paper.TABLE_III]
    keys = [
        k
        for k in _columns(scenario, results, paper_keys)
        if k in done or k in skipped or k in paper_keys
    ]
    header = ["error"]
    for key in keys:
        header += [f"{visit_name(key)} paper", f"{visit_name(key)} twin"]

    def twin_value(key: VisitKey, get: Callable[[Mapping[str, Any]], Any], spec: str) -> str:
        if key not in done:
            return "skipped" if key in skipped else NA
        value = get(done[key])
        return "n/a" if value is None else fmt(value, spec)

    def row(
        label: str,
        from_paper: Callable[[paper.PaperErrors], Any] | None,
        from_twin: Callable[[Mapping[str, Any]], Any],
        spec: str,
    ) -> list[str]:
        out = [label]
        for key in keys:
            col = paper.table_iii(*key)
            out.append(fmt(from_paper(col), spec) if col and from_paper else NA)
            out.append(twin_value(key, from_twin, spec))
        return out

    def errors(frame: str, field: str) -> Callable[[Mapping[str, Any]], Any]:
        return lambda e: error(e, frame, field)

    def world_points(e: Mapping[str, Any]) -> Any:
        return error(e, "world", "points")

    rows = [
        row(
            "distance travelled [m] ³", None, lambda e: number(e.get("distance_travelled_m")), ".1f"
        ),
        row(
            "world: pixel error [px]", lambda p: p.world_pixel, errors("world", "pixel_mean"), ".2f"
        ),
        row(
            "world: 3D error [mm]",
            lambda p: p.world_3d_mm,
            errors("world", "error_3d_mean_mm"),
            ".2f",
        ),
        row(
            "world: points",
            lambda p: paper.REFERENCE_POINTS,
            world_points,
            ".0f",
        ),
        row(
            "local: pixel error [px]", lambda p: p.local_pixel, errors("local", "pixel_mean"), ".2f"
        ),
        row(
            "local: 3D error [mm]",
            lambda p: p.local_3d_mm,
            errors("local", "error_3d_mean_mm"),
            ".2f",
        ),
        row("local: points", None, errors("local", "points"), ".0f"),
    ]
    lines = ["## Table III: mean errors (paper | twin)", ""]
    lines += table(header, rows)
    lines += [
        "",
        "World: against the reference set measured from the origin (the paper's 70 points "
        "for cameras 1 and 2). Local: on the calibration's own data, in the frame of the "
        "parent's station. n/a: the twin has no reference set for that camera (the paper "
        "had none for camera 3 either).",
        "",
        f"³ The paper gives only the whole route's length, about {paper.ROUTE_LENGTH_M:.0f} m, "
        "not the distance at each visit.",
        "",
    ]
    return lines


def _repeatability(results: Results) -> list[str]:
    twin = {str(k): vector(v, 3) for k, v in mapping(results.get("repeatability_mm")).items()}
    by_camera: dict[str, list[tuple[int, tuple[float, ...]]]] = {}
    for entry in calibrations(results):
        pos = vector(mapping(entry.get("parameters")).get("position_mm"), 3)
        if pos is not None:
            cam, visit = visit_key(entry)
            by_camera.setdefault(cam, []).append((visit, pos))
    derived = []
    for cam, visits in by_camera.items():
        if twin.get(cam) is None and len(visits) >= 2:
            visits.sort()
            first, second = visits[0][1], visits[1][1]
            twin[cam] = tuple(b - a for a, b in zip(first, second, strict=True))
            derived.append(cam)
    cams = list(paper.REPEATABILITY_MM) + sorted(c for c in twin if c not in paper.REPEATABILITY_MM)

    def vec_row(cam: str, source: str, v: Sequence[float] | None) -> list[str]:
        if v is None:
            return [cam, source, NA, NA, NA, NA]
        return [cam, source, *(f"{c:.1f}" for c in v), f"{math.sqrt(sum(c * c for c in v)):.1f}"]

    rows = []
    for cam in cams:
        rows.append(vec_row(cam, "paper", paper.REPEATABILITY_MM.get(cam)))
        rows.append(vec_row(cam, "twin", twin.get(cam)))
    lines = [
        "## Repeatability: second calibrated position minus the first",
        "",
        *table(("camera", "source", "dX [mm]", "dY [mm]", "dZ [mm]", "length [mm]"), rows),
        "",
        "The paper's values are those of its text (Section IV); its Table II gives 36.7 mm, "
        "not 37.7 mm, for camera 1's dX.",
    ]
    if derived:
        lines += [
            "",
            "Twin values of " + ", ".join(derived) + " computed from the calibrated positions "
            "(the results hold no repeatability for them).",
        ]
    return [*lines, ""]


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
    lines += _table_ii(scenario, results)
    lines += _table_iii(scenario, results)
    lines += _repeatability(results)
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
