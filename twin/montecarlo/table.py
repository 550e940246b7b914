"""The trial table: one CSV row per trial and camera visit, appended as trials finish.

Each finished trial is appended in one write and flushed to disk, so a run killed at any
moment keeps every trial it finished; a last line cut short, or a trial with fewer rows
than planned, is dropped when the table is opened again. Floats are written with
``repr``, so a table read back holds exactly the numbers that were written.
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from twin.montecarlo.trial import COLUMNS


def _format(value: Any) -> str:
    if isinstance(value, float):
        return "nan" if math.isnan(value) else repr(value)
    return str(value)


def _parse(text: str, kind: type) -> Any:
    if kind is float:
        return float(text)
    if kind is int:
        return int(text)
    return text


def format_rows(rows: Iterable[dict[str, Any]]) -> str:
    """CSV lines (no header) of ``rows``, in :data:`COLUMNS` order."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    for row in rows:
        writer.writerow([_format(row[c]) for c in COLUMNS])
    return buf.getvalue()


def read_table(path: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """The whole rows of a trial table (a last line cut short is left out).

    Raises:
        FileNotFoundError: if there is no table. ValueError: for a header other than
            :data:`COLUMNS` or a whole row that does not parse, naming the line.
    """
    path = Path(path)
    text = path.read_text()
    if not text.endswith("\n"):
        text = text[: text.rfind("\n") + 1]
    lines = text.splitlines()
    if not lines:
        return []
    header = next(csv.reader([lines[0]]))
    if header != list(COLUMNS):
        missing = [c for c in COLUMNS if c not in header]
        if header[:3] == list(COLUMNS)[:3] and missing:
            raise ValueError(
                f"{path}: a trial table of an earlier version, without the columns "
                f"{', '.join(missing)}: start the run again with --overwrite"
            )
        raise ValueError(f"{path}: not a trial table (header {header[:3]}...)")
    rows = []
    for number, fields in enumerate(csv.reader(lines[1:]), start=2):
        if len(fields) != len(COLUMNS):
            raise ValueError(f"{path}:{number}: {len(fields)} fields, expected {len(COLUMNS)}")
        try:
            pairs = zip(COLUMNS.items(), fields, strict=True)
            rows.append({c: _parse(f, k) for (c, k), f in pairs})
        except ValueError as exc:
            raise ValueError(f"{path}:{number}: {exc}") from None
    return rows


def sort_rows(rows: Iterable[dict[str, Any]], configs: Sequence[str]) -> list[dict[str, Any]]:
    """Rows in a canonical order: configuration (as in ``configs``), trial, then the rows
    of a trial in their own order."""
    order = {c: i for i, c in enumerate(configs)}
    indexed = list(enumerate(rows))
    indexed.sort(key=lambda ir: (order.get(ir[1]["config"], len(order)), ir[1]["trial"], ir[0]))
    return [r for _, r in indexed]


class TrialTable:
    """A trial table on disk, opened for appending.

    Args:
        path: the CSV file (created with its header if missing).
        rows_per_trial: rows each trial writes; a trial found with fewer is dropped.
    """

    def __init__(self, path: str | os.PathLike[str], rows_per_trial: int) -> None:
        self.path = Path(path)
        self.rows_per_trial = rows_per_trial
        rows = read_table(self.path) if self.path.exists() else []
        counts: dict[tuple[str, int], int] = {}
        for r in rows:
            key = (r["config"], r["trial"])
            counts[key] = counts.get(key, 0) + 1
        whole = {k for k, n in counts.items() if n == rows_per_trial}
        self.rows = [r for r in rows if (r["config"], r["trial"]) in whole]
        self.done: set[tuple[str, int]] = whole
        # Rewrite without what a kill left half-written, then append from there.
        self._write_all(self.rows)
        self._file = self.path.open("a", encoding="utf-8", newline="")

    def _write_all(self, rows: list[dict[str, Any]]) -> None:
        tmp = self.path.with_suffix(self.path.suffix + ".tmp")
        tmp.write_text(",".join(COLUMNS) + "\n" + format_rows(rows), encoding="utf-8")
        os.replace(tmp, self.path)

    def append(self, *trials: Sequence[dict[str, Any]]) -> None:
        """Append the rows of finished trials (one sequence a trial) and flush them to
        disk, once for all of them (a chunk of the batch fidelity is one write)."""
        for rows in trials:
            if len(rows) != self.rows_per_trial:
                raise ValueError(f"a trial has {self.rows_per_trial} rows, got {len(rows)}")
        self._file.write("".join(format_rows(rows) for rows in trials))
        self._file.flush()
        os.fsync(self._file.fileno())
        for rows in trials:
            self.rows.extend(rows)
            self.done.add((rows[0]["config"], rows[0]["trial"]))

    def finish(self, configs: Sequence[str]) -> list[dict[str, Any]]:
        """Close the table and rewrite it in canonical order; returns the sorted rows."""
        self.close()
        self.rows = sort_rows(self.rows, configs)
        self._write_all(self.rows)
        return self.rows

    def close(self) -> None:
        if not self._file.closed:
            self._file.close()

    def __enter__(self) -> TrialTable:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
