"""Correspondence files: one row per point, ``x,y,z,u,v`` (world coordinates, pixels)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

COLUMNS = ("x", "y", "z", "u", "v")
UNIT_SCALE = {"m": 1.0, "mm": 1e-3}


class PointsFileError(ValueError):
    """A correspondence file that cannot be read; the message names file, row and column."""


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def read_points_csv(
    path: str | Path, units: str = "m"
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Read ``x,y,z,u,v`` rows. A first row that is not numeric is taken as a header.

    Args:
        path: the CSV file.
        units: unit of x, y, z in the file: "m" or "mm"; returned points are in metres.

    Returns:
        points_3d (N, 3) in m, pixels (N, 2).

    Raises:
        PointsFileError: naming the file, the row (1-based, as an editor shows it) and the
            column of the first problem.
    """
    path = Path(path)
    if units not in UNIT_SCALE:
        raise ValueError(f"units must be one of {sorted(UNIT_SCALE)}, got {units!r}")
    try:
        text = path.read_text()
    except OSError as exc:
        raise PointsFileError(f"{path}: cannot read the file ({exc.strerror})") from None
    rows = [(i + 1, r) for i, r in enumerate(csv.reader(text.splitlines())) if r and any(r)]
    if rows and not all(_is_number(c) for c in rows[0][1]):
        header = [c.strip().lower() for c in rows[0][1]]
        if header != list(COLUMNS):
            raise PointsFileError(
                f"{path}: row {rows[0][0]}: header {','.join(header)!r} does not match "
                f"the expected columns {','.join(COLUMNS)!r}"
            )
        rows = rows[1:]
    if not rows:
        raise PointsFileError(f"{path}: no data rows (expected columns {','.join(COLUMNS)})")
    values = np.empty((len(rows), 5))
    for k, (line, row) in enumerate(rows):
        if len(row) != 5:
            missing = COLUMNS[len(row)] if len(row) < 5 else None
            what = f"missing column {missing!r}" if missing else f"{len(row)} columns"
            raise PointsFileError(
                f"{path}: row {line}: {what}; expected 5 columns {','.join(COLUMNS)}"
            )
        for c, cell in enumerate(row):
            try:
                values[k, c] = float(cell)
            except ValueError:
                raise PointsFileError(
                    f"{path}: row {line}, column {COLUMNS[c]!r}: {cell.strip()!r} is not a number"
                ) from None
            if not np.isfinite(values[k, c]):
                raise PointsFileError(
                    f"{path}: row {line}, column {COLUMNS[c]!r}: {cell.strip()!r} is not finite"
                )
    return values[:, :3] * UNIT_SCALE[units], values[:, 3:]


def write_points_csv(
    path: str | Path,
    points_3d: NDArray[np.float64],
    pixels: NDArray[np.float64],
    units: str = "m",
) -> None:
    """Write correspondences as ``x,y,z,u,v`` with a header; points given in metres."""
    scale = 1.0 / UNIT_SCALE[units]
    with Path(path).open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(COLUMNS)
        for p, q in zip(points_3d, pixels, strict=True):
            w.writerow([f"{v:.6f}" for v in p * scale] + [f"{v:.4f}" for v in q])
