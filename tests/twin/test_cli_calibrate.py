"""``twin calibrate`` on the shipped example and on broken files."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from calib.io import PointsFileError, load_camera, read_points_csv, write_points_csv
from calib.synthetic import led_points, paper_camera
from twin.cli import build_parser, main
from twin.cli import calibrate as calibrate_cli

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "camera1_points.csv"
TRUTH = ROOT / "examples" / "camera1_truth.json"


def calibrate(*args: str) -> int:
    return main(["calibrate", *args])


def test_example_calibration_writes_json_and_camera(tmp_path, capsys) -> None:
    out_json, out_cam = tmp_path / "r.json", tmp_path / "cam.json"
    code = calibrate(
        str(EXAMPLE), "--image-size", "320", "240", "--units", "mm", "--pixel-size", "0.015",
        "--out", str(out_cam), "--json", str(out_json),
    )  # fmt: skip
    assert code == 0
    printed = capsys.readouterr().out
    assert "pixel_error" in printed
    assert "f_px" in printed
    d = json.loads(out_json.read_text())
    assert d["model"] == "tsai"
    for key in ("f_px", "cx", "cy", "sx", "kappa1_px", "kappa1_mm", "rotation_deg", "position"):
        assert key in d["parameters"]
        assert key in d["std"]
    for key in ("pixel_error_mean", "pixel_error_rms", "pixel_error_max", "error_3d_mean"):
        assert key in d["metrics"]
    truth = load_camera(TRUTH)
    # Position in the input units (mm), within 4 sigma of the truth.
    pos, std = np.array(d["parameters"]["position"]), np.array(d["std"]["position"])
    assert np.all(np.abs(pos - truth.position * 1e3) < 4 * std)
    assert d["parameters"]["kappa1_mm"] == pytest.approx(d["parameters"]["kappa1_px"] / 0.015**2)
    assert d["metrics"]["error_3d_mean"] > 0.5  # mm: 2 mm 3D noise + 0.3 px pixel noise
    cam = load_camera(out_cam)
    assert_allclose(cam.position * 1e3, pos)


@pytest.mark.parametrize("suffix", [".yaml", ".camera_info.yaml"])
def test_camera_export_formats(tmp_path, suffix) -> None:
    out = tmp_path / f"cam{suffix}"
    assert (
        calibrate(str(EXAMPLE), "--image-size", "320", "240", "--units", "mm", "--out", str(out))
        == 0
    )
    assert load_camera(out).image_size == (320, 240)


def test_opencv_model(tmp_path) -> None:
    out_json = tmp_path / "r.json"
    args = [str(EXAMPLE), "--image-size", "320", "240", "--units", "mm", "--model", "opencv"]
    assert calibrate(*args, "--json", str(out_json)) == 0
    d = json.loads(out_json.read_text())
    assert d["model"] == "opencv"
    assert {"fx", "fy", "k1", "k2", "f_px", "sx"} <= set(d["parameters"])
    assert d["metrics"]["pixel_error_mean"] < 1.0


def test_console_script_runs() -> None:
    exe = Path(sys.executable).with_name("twin")
    proc = subprocess.run([str(exe), "calibrate", "--help"], capture_output=True, text=True)
    assert proc.returncode == 0
    assert "--image-size" in proc.stdout


def write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "pts.csv"
    p.write_text(text)
    return p


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("x,y,z,u\n1,2,3,4\n", "header 'x,y,z,u' does not match the expected columns"),
        ("1,2,3,4\n", "row 1: missing column 'v'"),
        ("1,2,3,4,5\n1,2,3,4,5,6\n", "row 2: 6 columns; expected 5"),
        ("x,y,z,u,v\n1,2,3,4,5\n1,2,x3,4,5\n", "row 3, column 'z': 'x3' is not a number"),
        ("x,y,z,u,v\n1,2,3,nan,5\n", "row 2, column 'u': 'nan' is not finite"),
        ("x,y,z,u,v\n", "no data rows"),
        ("x,y,z,u,v\n1,2,[/z],4,5\n", r"row 2, column 'z': '\[/z\]' is not a number"),
    ],
)
def test_bad_csv_names_file_row_and_column(tmp_path, capsys, text, message) -> None:
    path = write(tmp_path, text)
    with pytest.raises(PointsFileError, match=message):
        read_points_csv(path)
    code = calibrate(str(path), "--image-size", "320", "240")
    assert code == 2
    err = capsys.readouterr().err
    assert str(path) in err.replace("\n", "")
    assert "error" in err
    assert re.search(message, err.replace("\n", " "))  # printed as it is, not as markup


def test_paths_are_printed_as_they_are(tmp_path, capsys) -> None:
    # Brackets in a path are text, not console markup ("a[/b]c" is a closing tag).
    (tmp_path / "a[").mkdir()
    points = tmp_path / "a[" / "b]c.csv"
    points.write_bytes(EXAMPLE.read_bytes())
    out = tmp_path / "a[" / "bold]r.json"
    args = ["--image-size", "320", "240", "--units", "mm"]
    assert calibrate(str(points), *args, "--json", str(out)) == 0
    printed = " ".join(capsys.readouterr().out.split())
    assert f"result written to {out}" in printed
    missing = tmp_path / "a[" / "red]x.csv"
    assert calibrate(str(missing), *args) == 2
    assert f"{missing}: cannot read the file" in capsys.readouterr().err


def test_missing_file_and_bad_options(tmp_path, capsys) -> None:
    assert calibrate(str(tmp_path / "none.csv"), "--image-size", "320", "240") == 2
    assert "cannot read the file" in capsys.readouterr().err
    assert calibrate(str(EXAMPLE), "--image-size", "320", "240", "--out", "cam.txt") == 2
    assert "unknown camera file type" in capsys.readouterr().err
    args = [str(EXAMPLE), "--image-size", "100", "240", "--units", "mm"]
    assert calibrate(*args) == 2
    assert "outside the 100x240 image" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        calibrate(str(EXAMPLE), "--image-size", "320", "240", "--units", "inch")
    assert exit_.value.code == 2  # bad input, as documented
    assert "--units: invalid choice: 'inch'" in capsys.readouterr().err


@settings(max_examples=30, deadline=None)
@given(
    st.lists(
        st.tuples(*[st.floats(-1e4, 1e4, allow_nan=False)] * 3, *[st.floats(0, 500)] * 2),
        min_size=1, max_size=20,
    ),
    st.sampled_from(["m", "mm"]),
)  # fmt: skip
def test_points_csv_round_trip(tmp_path_factory, rows, units) -> None:
    arr = np.array(rows, dtype=float)
    pts = arr[:, :3] / (1e3 if units == "mm" else 1.0)
    path = tmp_path_factory.mktemp("csv") / "p.csv"
    write_points_csv(path, pts, arr[:, 3:], units=units)
    p3, uv = read_points_csv(path, units)
    # Written with 6 decimals in the file's units and 4 decimals in pixels.
    assert_allclose(p3, pts, atol=(1e-6 if units == "m" else 1e-9) * 0.51)
    assert_allclose(uv, arr[:, 3:], atol=0.51e-4)


def test_duplicated_rows_are_merged_and_reported(tmp_path, capsys) -> None:
    # Every row of the example twice: the same std as the example, and the count reported.
    lines = EXAMPLE.read_text().splitlines()
    twice = tmp_path / "twice.csv"
    twice.write_text("\n".join([lines[0], *(row for row in lines[1:] for _ in (0, 1))]) + "\n")
    args = ["--image-size", "320", "240", "--units", "mm"]
    assert calibrate(str(EXAMPLE), *args, "--json", str(tmp_path / "once.json")) == 0
    assert calibrate(str(twice), *args, "--json", str(tmp_path / "twice.json")) == 0
    printed = capsys.readouterr().out
    assert "70 duplicate rows merged" in printed
    assert "a copy of a row is not a second measurement" in printed.replace("\n", " ")
    once = json.loads((tmp_path / "once.json").read_text())
    merged = json.loads((tmp_path / "twice.json").read_text())
    assert merged["std"].keys() == once["std"].keys()
    for key, std in once["std"].items():
        assert_allclose(merged["std"][key], std, rtol=1e-12, err_msg=key)
    assert (merged["n_points"], merged["duplicates"], merged["duplicates_merged"]) == (70, 70, True)
    assert (once["duplicates"], once["duplicates_merged"]) == (0, False)
    assert any("70 of the 140 correspondences" in note for note in merged["notes"])
    # Kept on request: counted, and the std shrink as for 140 independent rows.
    assert (
        calibrate(str(twice), *args, "--keep-duplicates", "--json", str(tmp_path / "k.json")) == 0
    )
    kept = json.loads((tmp_path / "k.json").read_text())
    assert (kept["n_points"], kept["duplicates"], kept["duplicates_merged"]) == (140, 70, False)
    assert kept["std"]["f_px"] < 0.75 * once["std"]["f_px"]


def test_millimetres_read_as_metres_warn_and_name_units(tmp_path, capsys) -> None:
    # The example is in millimetres; the default unit is metres.
    out = tmp_path / "r.json"
    assert calibrate(str(EXAMPLE), "--image-size", "320", "240", "--json", str(out)) == 0
    printed = " ".join(capsys.readouterr().out.split())
    assert "warning: the camera is 5.44 km from its points" in printed
    assert "x,y,z were read in metres (--units m, the default)" in printed
    assert "run again with --units mm" in printed
    d = json.loads(out.read_text())
    assert len(d["warnings"]) == 1
    assert "--units mm" in d["warnings"][0]
    assert d["warnings"][0] in d["notes"]
    # In the right unit: no warning.
    args = ["--image-size", "320", "240", "--units", "mm", "--json", str(out)]
    assert calibrate(str(EXAMPLE), *args) == 0
    assert "warning" not in capsys.readouterr().out
    d = json.loads(out.read_text())
    assert d["warnings"] == []
    assert not any("--units" in note for note in d["notes"])


def test_metres_read_as_millimetres_warn_and_name_units(tmp_path, capsys) -> None:
    cam = paper_camera(1)
    rng = np.random.default_rng(3)
    pts = led_points(cam, 70, rng)
    path = tmp_path / "metres.csv"
    write_points_csv(path, pts, cam.project(pts) + rng.normal(0.0, 0.3, (70, 2)))
    assert calibrate(str(path), "--image-size", "320", "240", "--units", "mm") == 0
    printed = " ".join(capsys.readouterr().out.split())
    assert "lengths look 1000 times too small" in printed
    assert "run again without --units mm" in printed
    assert calibrate(str(path), "--image-size", "320", "240") == 0
    assert "warning" not in capsys.readouterr().out


def test_a_nearly_coplanar_point_cloud_is_noted(tmp_path, capsys) -> None:
    # The library warns (DegenerateGeometryWarning) without a note; the command keeps it.
    cam = paper_camera(1)
    rng = np.random.default_rng(4)
    pts = led_points(cam, 70, rng)
    pts[:, 2] = -0.38 + 0.01 * rng.standard_normal(70)
    uv = cam.project(pts)
    keep = cam.in_image(uv)
    path = tmp_path / "thin.csv"
    write_points_csv(path, pts[keep], uv[keep] + rng.normal(0.0, 0.3, (keep.sum(), 2)))
    out = tmp_path / "r.json"
    assert calibrate(str(path), "--image-size", "320", "240", "--json", str(out)) == 0
    assert "note: Tsai's non-coplanar calibration: the points are nearly coplanar" in (
        " ".join(capsys.readouterr().out.split())
    )
    assert any("nearly coplanar" in note for note in json.loads(out.read_text())["notes"])


def calibrate_subparser():
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    return sub.choices["calibrate"]


def test_every_option_states_its_default() -> None:
    parser = calibrate_subparser()
    options = [a for a in parser._actions if a.option_strings and a.dest != "help"]
    assert {"--image-size", "--units", "--pixel-size", "--keep-duplicates"} <= {
        o for a in options for o in a.option_strings
    }
    for action in options:
        assert "default" in action.help, action.option_strings
    assert "(default: m)" in parser.format_help()


@pytest.mark.parametrize(
    ("args", "argument"),
    [
        (["--image-size", "0", "240"], "--image-size"),
        (["--image-size", "320", "-1"], "--image-size"),
        (["--image-size", "320", "2.5"], "--image-size"),
        (["--image-size", "1e3", "240"], "--image-size"),
        (["--image-size", "99999999999", "240"], "--image-size"),
        (["--image-size", "320", "240", "--pixel-size", "0"], "--pixel-size"),
        (["--image-size", "320", "240", "--pixel-size", "-0.015"], "--pixel-size"),
        (["--image-size", "320", "240", "--pixel-size", "nan"], "--pixel-size"),
        (["--image-size", "320", "240", "--pixel-size", "inf"], "--pixel-size"),
        (["--image-size", "320", "240", "--pixel-size", "1e-300"], "--pixel-size"),
        (["--image-size", "320", "240", "--pixel-size", "15"], "--pixel-size"),
        (["--image-size", "320", "240", "--pixel-size", "fine"], "--pixel-size"),
        (["--image-size", "320", "240", "--model", "pinhole"], "--model"),
        (["--image-size", "320"], "--image-size"),
    ],
)
def test_bad_option_values_exit_2_naming_the_argument(capsys, args, argument) -> None:
    with pytest.raises(SystemExit) as exit_info:
        calibrate(str(EXAMPLE), "--units", "mm", *args)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {argument}" in err
    assert "expected" in err or "invalid choice" in err
    assert "Traceback" not in err


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--tangential"], "--tangential has no effect with --model tsai; expected it with"),
        (["--k3"], "--k3 has no effect with --model tsai; expected it with --model opencv"),
        (["--model", "opencv", "--pixel-size", "0.015"], "--pixel-size has no effect with"),
    ],
)
def test_options_the_model_would_ignore(capsys, args, message) -> None:
    assert calibrate(str(EXAMPLE), "--image-size", "320", "240", "--units", "mm", *args) == 2
    captured = capsys.readouterr()
    assert message in captured.err
    assert captured.out == ""


def tree(folder: Path) -> dict[str, bytes | None]:
    """Every path under ``folder`` with its content (None for a folder)."""
    return {
        str(p.relative_to(folder)): None if p.is_dir() else p.read_bytes()
        for p in sorted(folder.rglob("*"))
    }


@pytest.mark.parametrize(
    ("outputs", "message"),
    [
        (["--out", "{dir}"], "--out {dir}: is a folder; expected the name of a file"),
        (["--out", "{dir}/cam.json/"], "is a folder; expected the name of a file"),
        (["--out", "{file}/cam.json"], "--out {file}/cam.json: lies under the file {file}"),
        (["--out", "{file}/a/b/cam.yaml"], "lies under the file {file}; expected a folder"),
        (["--json", "{dir}"], "--json {dir}: is a folder; expected the name of a file"),
        (["--json", "{file}/r.json"], "--json {file}/r.json: lies under the file {file}"),
        (["--json", "{points}"], "--json {points}: is the points file; expected another file"),
        (["--out", "{points}"], "--out {points}: is the points file; expected another file"),
        (["--out", "{dir}/cam.txt"], "--out {dir}/cam.txt: unknown camera file type; use .json"),
        (["--out", "{dir}/c.json", "--json", "{dir}/c.json"], "name the same file; expected two"),
        (["--out", "{dir}/new/cam.txt", "--json", "{dir}/new/r.json"], "--out {dir}/new/cam.txt:"),
        (["--out", "{dir}/ok.json", "--json", "{file}/r.json"], "--json {file}/r.json: lies"),
    ],
)
def test_output_paths_that_cannot_be_written(tmp_path, capsys, outputs, message) -> None:
    # Each is an error naming the option and what was expected, exit 2, and nothing written.
    (tmp_path / "file").write_text("not a directory")
    (tmp_path / "cam.json").mkdir()
    points = tmp_path / "points.csv"
    points.write_bytes(EXAMPLE.read_bytes())
    names = {"dir": str(tmp_path), "file": str(tmp_path / "file"), "points": str(points)}
    args = [a.format(**names) for a in outputs]
    before = tree(tmp_path)
    assert calibrate(str(points), "--image-size", "320", "240", "--units", "mm", *args) == 2
    captured = capsys.readouterr()
    assert message.format(**names) in captured.err
    assert captured.out == ""  # rejected before the calibration
    assert tree(tmp_path) == before


def test_a_write_that_fails_leaves_nothing_behind(tmp_path, capsys, monkeypatch) -> None:
    def unreadable(path: Path) -> None:
        raise ValueError("the written camera does not read back")

    monkeypatch.setattr(calibrate_cli, "load_camera", unreadable)
    before = tree(tmp_path)
    args = ["--image-size", "320", "240", "--units", "mm"]
    outputs = ["--json", str(tmp_path / "a" / "r.json"), "--out", str(tmp_path / "b" / "c.json")]
    assert calibrate(str(EXAMPLE), *args, *outputs) == 2
    err = capsys.readouterr().err
    assert f"--out {tmp_path / 'b' / 'c.json'}: the written camera does not read back" in err
    assert tree(tmp_path) == before  # neither file, nor the folders made for them


def test_the_json_output_is_strict_json() -> None:
    # A parameter the data do not determine has a NaN std: written as null, not NaN.
    d = {"std": {"f_px": float("nan"), "position": [1.0, float("inf"), -float("inf")]}}

    def reject(name: str) -> None:
        raise AssertionError(f"{name} in the JSON output")

    back = json.loads(calibrate_cli.result_json(d), parse_constant=reject)
    assert back == {"std": {"f_px": None, "position": [1.0, None, None]}}


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(*[st.floats(-1e6, 1e6)] * 3, *[st.floats(-1, 330)] * 2),
        min_size=0, max_size=14,
    ),
    st.sampled_from([[], ["--model", "opencv"], ["--model", "opencv", "--tangential", "--k3"]]),
    st.booleans(),
)  # fmt: skip
def test_any_points_file_calibrates_or_exits_2(tmp_path_factory, rows, model, keep) -> None:
    folder = tmp_path_factory.mktemp("any")
    path = folder / "p.csv"
    path.write_text("".join(",".join(repr(v) for v in r) + "\n" for r in rows))
    args = ["--image-size", "320", "240", *model, "--json", str(folder / "r.json")]
    code = calibrate(str(path), *args, *(["--keep-duplicates"] if keep else []))
    assert code in (0, 2)
    assert (folder / "r.json").exists() == (code == 0)
