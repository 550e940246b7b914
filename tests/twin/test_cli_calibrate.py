"""``twin calibrate`` on the shipped example and on broken files."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from calib.io import PointsFileError, load_camera, read_points_csv, write_points_csv
from twin.cli import main

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
