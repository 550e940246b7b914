"""``twin calibrate`` on the inputs users really have: a left-handed world frame, pixels
counted from the bottom-left or from 1.

Each data set is synthetic with a known truth (:mod:`calib.synthetic`): the paper's
camera 1, 70 LED points, 0.3 px of pixel noise.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from numpy.testing import assert_allclose

from calib.handedness import (
    AXES,
    POOR_FIT_RMS_PX,
    camera_axes,
    is_poor_fit,
    mirror_explains,
    mirror_hints,
    mirror_points,
)
from calib.io import load_camera, write_points_csv
from calib.io.points_csv import PIXEL_ORIGINS, pixels_from_opencv, pixels_to_opencv
from calib.synthetic import led_points, paper_camera
from twin.cli import calibrate as calibrate_cli
from twin.cli import main

SIZE = ["--image-size", "320", "240"]
HEIGHT = 240


def calibrate(*args: str) -> int:
    return main(["calibrate", *args])


@pytest.fixture(scope="module")
def scene():
    """The truth, its 70 points (m) and their noisy pixels (OpenCV's convention)."""
    cam = paper_camera(1)
    rng = np.random.default_rng(11)
    pts = led_points(cam, 70, rng)
    return cam, pts, cam.project(pts) + rng.normal(0.0, 0.3, (70, 2))


def write(folder: Path, points: np.ndarray, pixels: np.ndarray, name: str = "p.csv") -> Path:
    path = folder / name
    write_points_csv(path, points, pixels)
    return path


def run_json(capsys, *args: str, out: Path) -> dict:
    code = calibrate(*args, "--json", str(out))
    assert code == 0, capsys.readouterr().err
    return json.loads(out.read_text())


def error_of(capsys, *args: str) -> str:
    assert calibrate(*args) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    return " ".join(captured.err.split())


# -- a left-handed world frame ------------------------------------------------------------


@pytest.mark.parametrize("axis", AXES)
def test_a_mirrored_frame_is_named_with_the_axis_to_negate(tmp_path, capsys, scene, axis):
    _, pts, uv = scene
    path = write(tmp_path, mirror_points(pts, axis), uv)
    err = error_of(capsys, str(path), *SIZE)
    assert "points lie behind the camera" in err  # the calibration's own finding, kept
    assert "the world frame appears mirrored (left-handed)" in err
    assert f"--mirror-axis {axis}" in err
    others = [f"--mirror-axis {a}" in err for a in AXES if a != axis]
    if axis == "z":  # the camera below its points: only z fits a camera mounted above
        assert not any(others)
        assert "the z axis appears reversed" in err
    else:  # x and y cannot be told apart: the message says so, and names both
        assert "z is up and the x or the y axis is reversed" in err
        assert "The data cannot tell which" in err


@pytest.mark.parametrize(
    ("reversed_axis", "option", "model"),
    [
        ("x", "x", "tsai"),
        ("y", "y", "tsai"),
        ("z", "z", "tsai"),
        ("y", "x", "tsai"),  # the other horizontal axis: the same camera in the user's frame
        ("x", "y", "opencv"),
    ],
)
def test_mirror_axis_calibrates_in_the_users_frame(
    tmp_path, capsys, scene, reversed_axis, option, model
):
    cam, pts, uv = scene
    user_points = mirror_points(pts, reversed_axis)
    path = write(tmp_path, user_points, uv)
    out_cam = tmp_path / "cam.json"
    args = [str(path), *SIZE, "--mirror-axis", option, "--model", model, "--out", str(out_cam)]
    d = run_json(capsys, *args, out=tmp_path / "r.json")
    printed = " ".join(capsys.readouterr().out.split())
    assert "camera axes in the file's frame (left-handed" in printed
    assert "describe the camera in the mirrored frame" in printed
    assert d["mirror_axis"] == option
    # The position in the user's frame, within 4 standard deviations of the truth there.
    truth = mirror_points(cam.position, reversed_axis)
    pos, std = np.array(d["parameters"]["position"]), np.array(d["std"]["position"])
    assert np.all(np.abs(pos - truth) < 4 * std), (pos, truth, std)
    # The camera's axes in the user's frame: the truth's, mirrored, within 4 standard
    # deviations of the rotation angles; a left-handed triple.
    true_axes = camera_axes(cam.world2cam_r, reversed_axis)
    tolerance_deg = 4 * np.linalg.norm(d["mirrored_frame"]["rotation_deg_std"])
    for name, direction in d["camera_axes"].items():
        angle = np.degrees(np.arccos(np.clip(np.dot(direction, true_axes[name]), -1, 1)))
        assert angle < tolerance_deg, (name, angle, tolerance_deg)
    right, down, forward = (np.array(d["camera_axes"][k]) for k in true_axes)
    assert np.dot(np.cross(right, down), forward) == pytest.approx(-1.0)
    # No rotation in a left-handed frame: it is given in the mirrored frame, where the
    # written camera lives and reprojects the mirrored points onto the pixels.
    assert "rotation_deg" not in d["parameters"]
    assert "rotation_deg" not in d["std"]
    assert d["mirrored_frame"]["axis"] == option
    assert len(d["mirrored_frame"]["rotation_deg"]) == 3
    written = load_camera(out_cam)
    assert_allclose(written.position, d["mirrored_frame"]["position"], atol=1e-9)
    assert_allclose(mirror_points(written.position, option), pos, atol=1e-9)
    residual = written.project(mirror_points(user_points, option)) - uv
    assert np.sqrt(np.mean(np.sum(residual**2, axis=1))) < 0.6
    assert any(f"--mirror-axis {option}" in note for note in d["notes"])


def test_mirror_axis_on_a_right_handed_frame_says_so(tmp_path, capsys, scene):
    _, pts, uv = scene
    path = write(tmp_path, pts, uv)
    err = error_of(capsys, str(path), *SIZE, "--mirror-axis", "y")
    assert "fit a camera in their mirror image" in err
    assert "without --mirror-axis y: the frame appears right-handed" in err


def test_a_right_handed_frame_is_not_doubted(tmp_path, capsys, scene):
    cam, pts, uv = scene
    path = write(tmp_path, pts, uv)
    d = run_json(capsys, str(path), *SIZE, out=tmp_path / "r.json")
    assert (d["mirror_axis"], d["pixel_origin"], d["one_based"]) == (None, "top-left", False)
    assert "mirrored_frame" not in d
    assert "rotation_deg" in d["parameters"]
    assert np.dot(d["camera_axes"]["optical_axis"], cam.optical_axis) > np.cos(np.radians(0.5))
    assert "mirror" not in capsys.readouterr().out


def test_an_image_turned_over_points_to_the_pixel_origin(tmp_path, capsys, scene):
    # A turned-over image is a mirror image too; the message names --pixel-origin.
    _, pts, uv = scene
    flipped = pixels_from_opencv(uv, origin="bottom-left", height=HEIGHT)
    path = write(tmp_path, pts, flipped)
    err = error_of(capsys, str(path), *SIZE)
    assert "run again with --pixel-origin bottom-left" in err
    # Given the option it calibrates; given it wrongly, the message says to drop it.
    assert calibrate(str(path), *SIZE, "--pixel-origin", "bottom-left") == 0
    capsys.readouterr()
    path = write(tmp_path, pts, uv, "top.csv")
    err = error_of(capsys, str(path), *SIZE, "--pixel-origin", "bottom-left")
    assert "run again without --pixel-origin bottom-left" in err


# -- pixel conventions --------------------------------------------------------------------


@pytest.mark.parametrize(
    ("origin", "one_based"), [("bottom-left", False), ("top-left", True), ("bottom-left", True)]
)
def test_pixel_conventions_calibrate_to_the_same_camera(tmp_path, capsys, scene, origin, one_based):
    cam, pts, uv = scene
    reference = run_json(capsys, str(write(tmp_path, pts, uv)), *SIZE, out=tmp_path / "ref.json")
    theirs = pixels_from_opencv(uv, origin=origin, one_based=one_based, height=HEIGHT)
    path = write(tmp_path, pts, theirs, "theirs.csv")
    options = ["--pixel-origin", origin, *(["--one-based"] if one_based else [])]
    d = run_json(capsys, str(path), *SIZE, *options, out=tmp_path / "r.json")
    assert (d["pixel_origin"], d["one_based"]) == (origin, one_based)
    for key, value in reference["parameters"].items():
        assert_allclose(d["parameters"][key], value, rtol=1e-7, atol=1e-9, err_msg=key)
    pos, std = np.array(d["parameters"]["position"]), np.array(d["std"]["position"])
    assert np.all(np.abs(pos - cam.position) < 4 * std)
    assert abs(d["parameters"]["f_px"] - cam.f) < 4 * d["std"]["f_px"]
    assert abs(d["parameters"]["cy"] - cam.cy) < 4 * d["std"]["cy"]


def test_one_based_is_applied_before_the_origin_flip() -> None:
    # MATLAB's first pixel (1, 1) at the bottom-left is OpenCV's (0, H - 1).
    corners = [[1.0, 1.0], [320.0, 240.0]]
    got = pixels_to_opencv(corners, origin="bottom-left", one_based=True, height=HEIGHT)
    assert_allclose(got, [[0.0, HEIGHT - 1.0], [319.0, 0.0]])
    assert_allclose(pixels_to_opencv(corners, one_based=True), [[0.0, 0.0], [319.0, 239.0]])


def test_a_bottom_left_origin_needs_the_image_height(tmp_path, capsys, scene) -> None:
    _, pts, uv = scene
    path = write(tmp_path, pts, uv)
    with pytest.raises(SystemExit) as exit_info:
        calibrate(str(path), "--pixel-origin", "bottom-left")
    assert exit_info.value.code == 2
    assert "--image-size" in capsys.readouterr().err
    args = argparse.Namespace(image_size=None, pixel_origin="bottom-left", one_based=False)
    with pytest.raises(ValueError, match="--pixel-origin bottom-left needs the image height"):
        calibrate_cli._input_pixels(args, uv)
    with pytest.raises(ValueError, match="need the image height H"):
        pixels_to_opencv(uv, origin="bottom-left")
    with pytest.raises(ValueError, match="pixel origin must be one of top-left, bottom-left"):
        pixels_to_opencv(uv, origin="centre", height=HEIGHT)


@pytest.mark.parametrize(
    ("args", "argument"),
    [(["--mirror-axis", "w"], "--mirror-axis"), (["--pixel-origin", "left"], "--pixel-origin")],
)
def test_bad_option_values_name_the_argument(tmp_path, capsys, scene, args, argument) -> None:
    _, pts, uv = scene
    with pytest.raises(SystemExit) as exit_info:
        calibrate(str(write(tmp_path, pts, uv)), *SIZE, *args)
    assert exit_info.value.code == 2
    assert f"argument {argument}: invalid choice" in capsys.readouterr().err


# -- the pure conversions -----------------------------------------------------------------

finite = st.floats(-1e6, 1e6, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(0, 20), st.just(3)), elements=finite),
       st.sampled_from(AXES))  # fmt: skip
def test_mirroring_twice_is_the_identity(points, axis) -> None:
    once = mirror_points(points, axis)
    assert_allclose(mirror_points(once, axis), points, rtol=0, atol=0)
    i = AXES.index(axis)
    assert_allclose(once[:, i], -points[:, i], rtol=0, atol=0)
    assert_allclose(np.delete(once, i, axis=1), np.delete(points, i, axis=1), rtol=0, atol=0)
    assert_allclose(mirror_points(points, None), points, rtol=0, atol=0)


@settings(max_examples=60, deadline=None)
@given(st.lists(finite, min_size=3, max_size=3), st.sampled_from(AXES))
def test_camera_axes_of_a_mirror_are_a_left_handed_orthonormal_triple(rotvec, axis) -> None:
    from scipy.spatial.transform import Rotation

    r = Rotation.from_rotvec(np.asarray(rotvec) % (2 * np.pi)).as_matrix()
    axes = np.array(list(camera_axes(r, axis).values()))
    assert_allclose(axes @ axes.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(axes) == pytest.approx(-1.0)
    assert_allclose(np.array(list(camera_axes(r, None).values())), r, atol=0)


@settings(max_examples=80, deadline=None)
@given(
    st.integers(1, 8000).flatmap(
        lambda h: st.tuples(
            st.just(h),
            arrays(np.float64, st.tuples(st.integers(0, 20), st.just(2)),
                   elements=st.floats(-1.0, h + 1.0)),
        )
    ),
    st.sampled_from(PIXEL_ORIGINS),
    st.booleans(),
)  # fmt: skip
def test_pixel_conversions_invert(case, origin, one_based) -> None:
    height, theirs = case
    kw = {"origin": origin, "one_based": one_based, "height": height}
    ours = pixels_to_opencv(theirs, **kw)
    assert_allclose(pixels_from_opencv(ours, **kw), theirs, atol=1e-9)
    assert_allclose(pixels_to_opencv(pixels_from_opencv(theirs, **kw), **kw), theirs, atol=1e-9)
    assert_allclose(ours[:, 0], theirs[:, 0] - one_based)  # u never flips
    if origin == "bottom-left":  # v runs the other way
        assert_allclose(ours[:, 1] + theirs[:, 1], height - 1 + one_based, atol=1e-9)


def test_when_a_mirror_explains_the_fit() -> None:
    assert not is_poor_fit(0.3)
    assert is_poor_fit(POOR_FIT_RMS_PX * 2)
    assert is_poor_fit(np.nan)
    assert mirror_explains(None, 0.4)  # the fit as given failed
    assert mirror_explains(40.0, 0.4)
    assert not mirror_explains(None, 3 * POOR_FIT_RMS_PX)  # the mirror fits poorly too
    assert not mirror_explains(1.2, 0.4)  # not clearly better


def test_the_scene_tells_which_axes() -> None:
    floor = np.array([[x, y, 0.0] for x in range(3) for y in range(3)], dtype=float)
    assert mirror_hints([1.0, 1.0, 2.5], floor) == ("x", "y", "v")
    assert mirror_hints([1.0, 1.0, -2.5], floor) == ("z",)
    assert mirror_hints([1.0, -6.0, 0.1], floor) == ("x", "y", "z", "v")  # level: no telling


def test_a_poor_fit_is_tried_mirrored_too(tmp_path, capsys, scene, monkeypatch) -> None:
    # Mirrored data fail outright in every case tried; a fit that instead ends poor (pixel
    # RMS far above any noise) is tried mirrored the same way.
    real = calibrate_cli._calibrate

    def poor_instead_of_failing(args, points, pixels):
        try:
            return real(args, points, pixels)
        except ValueError:
            return SimpleNamespace(metrics=SimpleNamespace(pixel=SimpleNamespace(rms=40.0))), []

    monkeypatch.setattr(calibrate_cli, "_calibrate", poor_instead_of_failing)
    _, pts, uv = scene
    err = error_of(capsys, str(write(tmp_path, mirror_points(pts, "z"), uv)), *SIZE)
    assert "the fit is poor (pixel RMS 40 px); but the points fit a camera in their mirror" in err
    assert "run again with --mirror-axis z" in err
