"""The report's sections that set the twin's numbers beside the paper's: Table II (the
calibrated parameters), Table III (the mean errors) and the repeatability of cameras visited
twice, paper | twin, in the paper's units (px, mm, deg)."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

from twin.report import paper
from twin.report.formatting import NA, fmt, table
from twin.report.reading import (
    Results,
    VisitKey,
    calibrations,
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


_PARAMETERS: tuple[tuple[str, Callable[[paper.PaperCalibration], Any], str, str], ...] = (
    ("f / pixel size [px]", lambda p: p.f_px, "f_px", ".1f"),
    ("image centre x [px]", lambda p: p.cx, "cx", ".1f"),
    ("image centre y [px]", lambda p: p.cy, "cy", ".1f"),
    ("kappa1 (paper's number; twin: 1/px²) ¹", lambda p: p.kappa1, "kappa1_px", ".3g"),
)


def table_ii_section(scenario: Scenario | None, results: Results) -> list[str]:
    """Table II's lines: each visit's calibrated parameters, paper | twin, with the notes on
    kappa1's unit and the rotation angles."""
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


def table_iii_section(scenario: Scenario | None, results: Results) -> list[str]:
    """Table III's lines: each visit's mean errors, world and local, paper | twin."""
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


def repeatability_section(results: Results) -> list[str]:
    """The repeatability's lines: second calibrated position minus the first, paper and twin
    (the twin's derived from its calibrations where the results hold none)."""
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
