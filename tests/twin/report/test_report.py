"""write_report: three figures and a Markdown page beside the paper's Tables II and III."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from tests.twin.report.figure_checks import Saved
from twin.report import write_report
from twin.scenario import Scenario

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
FIGURES = ("top_view.png", "error_vs_distance.png", "residuals.png")


def tables(text: str) -> list[list[str]]:
    """The Markdown tables of a text, each as its lines."""
    out: list[list[str]] = []
    current: list[str] = []
    for line in [*text.splitlines(), ""]:
        if line.startswith("|"):
            current.append(line)
        elif current:
            out.append(current)
            current = []
    return out


def cells(line: str) -> list[str]:
    """The cells of a table row (escaped pipes stay inside their cell)."""
    assert line.startswith("|"), line
    assert line.endswith("|"), line
    return [c.strip() for c in re.split(r"(?<!\\)\|", line[1:-1])]


def assert_valid_tables(text: str) -> None:
    found = tables(text)
    assert found, "no tables"
    for lines in found:
        assert len(lines) >= 2, lines
        n = len(cells(lines[0]))
        assert re.fullmatch(r"\|(---\|)+", lines[1]), lines[1]
        assert lines[1].count("---") == n
        for line in lines[2:]:
            assert len(cells(line)) == n, line


def section(text: str, title: str) -> str:
    """The text of the '## title...' section up to the next '## '."""
    start = text.index("## " + title)
    end = text.find("\n## ", start + 3)
    return text[start : end if end >= 0 else len(text)]


def row(text: str, label: str) -> list[str]:
    """The cells of the first table row whose first cell starts with ``label``."""
    for line in text.splitlines():
        if line.startswith("|") and cells(line)[0].startswith(label):
            return cells(line)
    raise AssertionError(f"no row {label!r}")


def assert_figures(out: Path, saved: dict[str, Saved]) -> None:
    """The report's three figures were drawn and written where it links them, each PNG the
    figure at its DPI."""
    assert set(saved) == set(FIGURES)
    for name in FIGURES:
        assert saved[name].path == out / "figures" / name
        assert saved[name].path.read_bytes().startswith(PNG_MAGIC), name
        saved[name].check_png()


def test_full_run(
    scenario: Scenario, results: dict[str, Any], tmp_path: Path, saved: dict[str, Saved]
) -> None:
    report = write_report(scenario, results, tmp_path)
    assert report == tmp_path / "report.md"
    assert_figures(tmp_path, saved)
    text = report.read_text(encoding="utf-8")
    assert_valid_tables(text)
    assert text.startswith("# Campaign report: paper_hall")
    assert "20080922" in text
    assert "geometric" in text
    for name in FIGURES:
        assert f"](figures/{name})" in text
    summary = section(text, "Summary")
    assert "Calibrated visits: 5 of 5 planned" in summary
    assert "12.3 mm" in summary
    assert "lost_lock" in summary
    recoveries = summary[summary.index("Recoveries by kind") :]
    assert row(recoveries, "child_turned")[1] == "1"
    assert row(recoveries, "total")[1] == "8"
    assert "prism_reaimed" not in summary[: summary.index("Recoveries by kind")]

    t2 = section(text, "Table II")
    f = row(t2, "f / pixel size")
    assert f[1:3] == ["770.3", "770.7"]  # cam1 (1st): paper | twin (truth + 0.44 px)
    assert f[9:11] == ["763.9", "770.7"]  # cam1 (2nd)
    assert row(t2, "position Z")[5] == "2075.6"  # cam3, paper
    assert row(t2, "kappa1 (paper")[1] == "4.33e-07"
    assert row(t2, "rotation about X")[1] == "115.5"

    t3 = section(text, "Table III")
    world_px = row(t3, "world: pixel error")
    assert world_px[1:3] == ["1.02", "0.31"]
    assert world_px[-2:] == ["8.54", "1.23"]
    assert "cam3 (1st) twin" in t3
    assert row(t3, "world: 3D error")[5:7] == ["—", "n/a"]  # cam3: no reference set
    assert row(t3, "local: 3D error")[-2:] == ["4.69", "0.55"]

    rep = section(text, "Repeatability")
    lines = [
        cells(line)
        for line in rep.splitlines()
        if line.startswith("| cam") and "source" not in line
    ]
    assert lines[0] == ["cam1", "paper", "37.7", "18.9", "-1.1", "42.2"]
    assert lines[1][:5] == ["cam1", "twin", "1.2", "-0.3", "0.1"]
    assert lines[2][:3] == ["cam2", "paper", "39.0"]
    truth = section(text, "Errors against the twin's truth")
    assert "18.3" in truth
    timing = section(text, "Time by stage")
    assert "78.3" in timing  # total of the stages


def test_skipped_visit_and_missing_parts(
    scenario: Scenario, results_skipped: dict[str, Any], tmp_path: Path, saved: dict[str, Saved]
) -> None:
    text = write_report(scenario, results_skipped, tmp_path).read_text(encoding="utf-8")
    assert_figures(tmp_path, saved)
    assert_valid_tables(text)
    summary = section(text, "Summary")
    assert "Calibrated visits: 4 of 5 planned" in summary
    assert "station_unreachable" in summary
    assert "partial run" in text
    t2 = section(text, "Table II")
    f = row(t2, "f / pixel size")
    assert f[7:9] == ["770.4", "skipped"]  # cam2 (2nd)
    t3 = section(text, "Table III")
    assert row(t3, "world: pixel error")[5:9] == ["—", "n/a", "4.04", "skipped"]
    # repeatability of cam1 computed from its two positions (equal offsets: zero)
    rep = section(text, "Repeatability")
    assert "computed from the calibrated positions" in rep
    assert "Time by stage" not in text


@pytest.mark.parametrize("kind", ["no_calibrations", "empty"])
def test_nothing_calibrated(
    scenario: Scenario, results: dict[str, Any], tmp_path: Path, kind: str, saved: dict[str, Saved]
) -> None:
    if kind == "empty":
        data: dict[str, Any] = {}
    else:
        data = {
            **results,
            "calibrations": [],
            "repeatability_mm": {},
            "parent_track": {"estimated": []},
        }
    text = write_report(scenario, data, tmp_path).read_text(encoding="utf-8")
    assert_figures(tmp_path, saved)
    assert_valid_tables(text)
    assert "Nothing was calibrated" in text
    assert "Calibrated visits: 0 of 5 planned" in text
    # the paper's numbers are still shown
    assert "770.3" in section(text, "Table II")
    assert "60.24" in section(text, "Table III")
