"""Correspondence files: one row per point, ``x,y,z,u,v`` (world coordinates, pixels).

Files are read as UTF-8, with or without the byte-order mark that spreadsheet programs put
at the start of the files they export (Excel's "CSV UTF-8"); a UTF-16 or UTF-32 file is
recognised by its byte-order mark. The file is streamed: memory grows with 40 bytes per
row, whatever the number of rows.
"""

from __future__ import annotations

import codecs
import csv
import math
from array import array
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

COLUMNS = ("x", "y", "z", "u", "v")
UNIT_SCALE = {"m": 1.0, "mm": 1e-3}

# Byte-order marks and the codec that reads past them; UTF-32's before UTF-16's, whose
# little-endian mark is a prefix of UTF-32's.
_BOMS = (
    (codecs.BOM_UTF32_LE, "utf-32"),
    (codecs.BOM_UTF32_BE, "utf-32"),
    (codecs.BOM_UTF16_LE, "utf-16"),
    (codecs.BOM_UTF16_BE, "utf-16"),
)


class PointsFileError(ValueError):
    """A correspondence file that cannot be read; the message names file, row and column."""


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _encoding(path: Path) -> str:
    """The codec for the file: UTF-16 or UTF-32 by their byte-order mark, else UTF-8 (a
    leading UTF-8 byte-order mark is skipped)."""
    with path.open("rb") as fh:
        head = fh.read(4)
    for bom, codec in _BOMS:
        if head.startswith(bom):
            return codec
    return "utf-8-sig"


def _undecodable(path: Path, encoding: str) -> str:
    """Where a file stops being text in ``encoding``: the row and the byte, for UTF-8."""
    if encoding != "utf-8-sig":
        return f"not {encoding.upper()} text"
    with path.open("rb") as fh:
        for line, raw in enumerate(fh, start=1):
            try:
                raw.decode(encoding)
            except UnicodeDecodeError as exc:
                return f"row {line}: byte {raw[exc.start : exc.start + 1]!r} is not UTF-8 text"
    return "not UTF-8 text"


def _row_values(path: Path, line: int, row: list[str]) -> list[float]:
    """The 5 numbers of a data row, or PointsFileError naming the row and column."""
    if len(row) != 5:
        missing = COLUMNS[len(row)] if len(row) < 5 else None
        what = f"missing column {missing!r}" if missing else f"{len(row)} columns"
        raise PointsFileError(f"{path}: row {line}: {what}; expected 5 columns {','.join(COLUMNS)}")
    values = []
    for c, cell in enumerate(row):
        try:
            v = float(cell)
        except ValueError:
            raise PointsFileError(
                f"{path}: row {line}, column {COLUMNS[c]!r}: {cell.strip()!r} is not a number"
            ) from None
        if not math.isfinite(v):
            raise PointsFileError(
                f"{path}: row {line}, column {COLUMNS[c]!r}: {cell.strip()!r} is not finite"
            )
        values.append(v)
    return values


def read_points_csv(
    path: str | Path, units: str = "m"
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Read ``x,y,z,u,v`` rows. A first row that is not numeric is taken as a header.

    Blank rows are skipped. The file may start with a byte-order mark (see the module
    docstring).

    Args:
        path: the CSV file.
        units: unit of x, y, z in the file: "m" or "mm"; returned points are in metres.

    Returns:
        points_3d (N, 3) in m, pixels (N, 2) in px.

    Raises:
        PointsFileError: naming the file, the row (1-based, as an editor shows it) and the
            column of the first problem.
    """
    path = Path(path)
    if units not in UNIT_SCALE:
        raise ValueError(f"units must be one of {sorted(UNIT_SCALE)}, got {units!r}")
    values = array("d")
    line = 0
    try:
        encoding = _encoding(path)
        with path.open(encoding=encoding, newline="") as fh:
            reader = csv.reader(fh)
            first = True
            for row in reader:
                line = reader.line_num
                if not any(row):
                    continue
                if first and not all(_is_number(c) for c in row):
                    header = [c.strip().lower() for c in row]
                    if header != list(COLUMNS):
                        raise PointsFileError(
                            f"{path}: row {line}: header {','.join(header)!r} does not match "
                            f"the expected columns {','.join(COLUMNS)!r}"
                        )
                else:
                    values.extend(_row_values(path, line, row))
                first = False
    except OSError as exc:
        raise PointsFileError(f"{path}: cannot read the file ({exc.strerror})") from None
    except UnicodeDecodeError:
        raise PointsFileError(
            f"{path}: {_undecodable(path, encoding)}; expected a text file of "
            f"{','.join(COLUMNS)} rows"
        ) from None
    except csv.Error as exc:
        raise PointsFileError(
            f"{path}: row {line + 1}: {exc}; expected {','.join(COLUMNS)} rows"
        ) from None
    if not values:
        raise PointsFileError(f"{path}: no data rows (expected columns {','.join(COLUMNS)})")
    table = np.frombuffer(values, dtype=np.float64).reshape(-1, 5)
    return table[:, :3] * UNIT_SCALE[units], table[:, 3:].copy()


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


PIXEL_ORIGINS = ("top-left", "bottom-left")


def _pixel_convention(
    pixels: NDArray[np.float64] | list, origin: str, height: int | None
) -> NDArray[np.float64]:
    """The pixels as a float (N, 2) copy, after checking ``origin`` and ``height``."""
    if origin not in PIXEL_ORIGINS:
        raise ValueError(f"pixel origin must be one of {', '.join(PIXEL_ORIGINS)}, got {origin!r}")
    if origin == "bottom-left" and height is None:
        raise ValueError(
            "pixels with the origin at the bottom-left need the image height H "
            "(v is turned into (H - 1) - v); got no height"
        )
    uv = np.array(pixels, dtype=float, copy=True)
    if uv.ndim != 2 or uv.shape[1] != 2:
        raise ValueError(f"pixels must be an (N, 2) array, got shape {uv.shape}")
    return uv


def pixels_to_opencv(
    pixels: NDArray[np.float64] | list,
    *,
    origin: str = "top-left",
    one_based: bool = False,
    height: int | None = None,
) -> NDArray[np.float64]:
    """Pixels written in another convention -> OpenCV's ((0, 0) the centre of the top-left
    pixel, v down).

    One-based indices (MATLAB's: the first pixel is 1) are made zero-based first,
    u' = u - 1, v' = v - 1; then a bottom-left origin (v up) is turned over,
    v' = (H - 1) - v, so that the centre of the bottom row goes to H - 1.

    Args:
        pixels: (N, 2) u, v in the file's convention, px.
        origin: "top-left" (OpenCV's) or "bottom-left".
        one_based: the file counts pixels from 1.
        height: image height H, px; needed for a bottom-left origin.

    Returns:
        (N, 2) pixels in OpenCV's convention (a copy).
    """
    uv = _pixel_convention(pixels, origin, height)
    if one_based:
        uv -= 1.0
    if origin == "bottom-left":
        uv[:, 1] = (height - 1) - uv[:, 1]
    return uv


def pixels_from_opencv(
    pixels: NDArray[np.float64] | list,
    *,
    origin: str = "top-left",
    one_based: bool = False,
    height: int | None = None,
) -> NDArray[np.float64]:
    """The inverse of :func:`pixels_to_opencv`: OpenCV pixels (N, 2) -> the given convention."""
    uv = _pixel_convention(pixels, origin, height)
    if origin == "bottom-left":
        uv[:, 1] = (height - 1) - uv[:, 1]
    if one_based:
        uv += 1.0
    return uv
