"""Markdown for the reports: numbers formatted or ``—`` when missing, table cells made
safe, tables padded to their header, durations for a reader."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

from twin.report.reading import number

NA = "—"
"""What a table cell shows when a value is not available."""


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


def duration(seconds: float | None) -> str:
    """A duration for a reader: seconds, with minutes or hours beside them when long;
    ``—`` for None."""
    if seconds is None:
        return NA
    if seconds < 60:
        return f"{seconds:.1f} s"
    minutes, rest = divmod(seconds, 60.0)
    if minutes < 60:
        return f"{seconds:.1f} s ({int(minutes)} min {rest:.0f} s)"
    hours, minutes = divmod(minutes, 60.0)
    return f"{seconds:.0f} s ({int(hours)} h {int(minutes)} min)"
