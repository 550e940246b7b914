"""The correspondence-file reader: what spreadsheets write, and nothing but PointsFileError."""

from __future__ import annotations

import codecs
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_array_equal

from calib.io import PointsFileError, read_points_csv

ROWS = st.lists(st.tuples(*[st.floats(-1e6, 1e6, allow_nan=False)] * 5), min_size=1, max_size=12)


def csv_text(rows: list[tuple[float, ...]], header: bool, newline: str) -> str:
    lines = (["x,y,z,u,v"] if header else []) + [",".join(repr(v) for v in r) for r in rows]
    return newline.join(lines) + newline


@settings(max_examples=60, deadline=None)
@given(
    rows=ROWS,
    header=st.booleans(),
    newline=st.sampled_from(["\n", "\r\n"]),
    encoding=st.sampled_from(["utf-8-sig", "utf-16", "utf-16-le", "utf-16-be", "utf-32"]),
)
def test_a_byte_order_mark_is_read_past(tmp_path_factory, rows, header, newline, encoding):
    # Spreadsheets save "CSV UTF-8" with a UTF-8 byte-order mark and "Unicode text" as
    # UTF-16 with one: the values read are those of the same file without the mark.
    folder = tmp_path_factory.mktemp("bom")
    text = csv_text(rows, header, newline)
    plain, marked = folder / "plain.csv", folder / "marked.csv"
    plain.write_bytes(text.encode("utf-8"))
    bom = {"utf-16-le": codecs.BOM_UTF16_LE, "utf-16-be": codecs.BOM_UTF16_BE}.get(encoding, b"")
    marked.write_bytes(bom + text.encode(encoding))
    expected = np.array(rows, dtype=float)
    for path in (plain, marked):
        p3, uv = read_points_csv(path)
        assert_array_equal(p3, expected[:, :3])
        assert_array_equal(uv, expected[:, 3:])


@pytest.mark.parametrize(
    "data",
    [
        b"\xef\xbb\xbfx,y,z,u,v\r\n1,2,3,4,5\r\n",
        b"\xef\xbb\xbf1,2,3,4,5\n",
        b"\xef\xbb\xbf X , Y ,z,u,v\n\n1,2,3,4,5\n",
        b"\xff\xfe" + "x,y,z,u,v\n1,2,3,4,5\n".encode("utf-16-le"),
    ],
    ids=["utf8-bom-header-crlf", "utf8-bom-no-header", "utf8-bom-spaced-header", "utf16le"],
)
def test_spreadsheet_exports(tmp_path, data) -> None:
    path = tmp_path / "p.csv"
    path.write_bytes(data)
    p3, uv = read_points_csv(path, "mm")
    assert_array_equal(p3, [[1e-3, 2e-3, 3e-3]])
    assert_array_equal(uv, [[4.0, 5.0]])


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (b"x,y,z,u,v\n1,2,3,4,5\n1,2,3,\xff4,5\n", r"row 3: byte b'\\xff' is not UTF-8 text"),
        (b'"' + b"1" * 200_000 + b'"\n', "row 1: field larger than field limit"),
        (b"\xff\xfe" + "x,y,z,u,v\n1,2,3,4,5\n".encode("utf-16-le")[:-1], "not UTF-16 text"),
    ],
    ids=["bad-utf8", "huge-field", "odd-utf16"],
)
def test_files_that_are_not_text(tmp_path, data, message) -> None:
    path = tmp_path / "p.csv"
    path.write_bytes(data)
    with pytest.raises(PointsFileError, match=message) as info:
        read_points_csv(path)
    assert str(path) in str(info.value)


@settings(max_examples=200, deadline=None)
@given(st.one_of(st.binary(max_size=300), st.text(max_size=300).map(str.encode)))
def test_any_content_gives_points_or_a_points_file_error(tmp_path_factory, data) -> None:
    path = tmp_path_factory.mktemp("any") / "p.csv"
    path.write_bytes(data)
    message = ""
    try:
        p3, uv = read_points_csv(path)
    except PointsFileError as exc:
        message = str(exc)
    else:
        assert p3.shape == (len(uv), 3)
        assert uv.shape == (len(p3), 2)
        assert np.isfinite(p3).all()
        assert np.isfinite(uv).all()
    assert not message or message.startswith(f"{path}: ")


def test_a_directory_is_not_a_file(tmp_path: Path) -> None:
    with pytest.raises(PointsFileError, match=r"cannot read the file \(Is a directory\)"):
        read_points_csv(tmp_path)
