"""A camera JSON file is read strictly: every malformed file (not JSON, not an object, a
key missing, a value of the wrong type or shape, NaN or infinity, a rotation that is not
one, a focal length that is not positive, a derived value that disagrees with the pose) is
refused with a ValueError naming the file and the key, never another exception; and a
file records what it belongs to."""

from __future__ import annotations

import copy
import json
import math
import re
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib.camera import TsaiCamera
from calib.camera_covariance import CAMERA_PARAMETERS
from calib.io.camera_files import (
    camera_to_dict,
    load_camera,
    load_camera_covariance,
    load_camera_identity,
    save_camera,
)
from calib.opencv_camera import OpenCVCamera, tsai2opencv
from calib.rotation import euler2matrix
from calib.synthetic import paper_camera

CAMERA = paper_camera(1)
VALID = camera_to_dict(CAMERA)
IDENTITY = {"scenario": "hall", "scenario_digest": "0123456789abcdef"}


def _file(folder: Path, data: Any, name: str = "cam.json") -> Path:
    path = folder / name
    path.write_text(json.dumps(data, allow_nan=True))
    return path


def _mutated(**changes: Any) -> dict[str, Any]:
    data = copy.deepcopy(VALID)
    for key, value in changes.items():
        if value is _DELETE:
            del data[key]
        else:
            data[key] = value
    return data


_DELETE = object()
ROTATION = VALID["world2cam_r"]


@pytest.mark.parametrize(
    ("data", "key", "expected"),
    [
        ([VALID], "", "expected a JSON object (a camera)"),
        ("camera", "", "expected a JSON object (a camera)"),
        (_mutated(f_px="770"), "f_px", 'expected a positive finite number, got "770"'),
        (_mutated(f_px=None), "f_px", "expected a positive finite number, got null"),
        (_mutated(f_px=True), "f_px", "expected a positive finite number, got true"),
        (_mutated(f_px=-770.0), "f_px", "expected a positive finite number"),
        (_mutated(f_px=0), "f_px", "expected a positive finite number"),
        (_mutated(f_px=math.inf), "f_px", "got Infinity"),
        (_mutated(cx=math.nan), "cx", "expected a finite number, got NaN"),
        (_mutated(sx=0.0), "sx", "expected a positive finite number"),
        (_mutated(kappa1_px=[1e-7]), "kappa1_px", "expected a finite number"),
        (_mutated(cy=_DELETE), "cy", "missing key 'cy'"),
        (_mutated(model=_DELETE), "model", "missing key 'model'"),
        (_mutated(model="pinhole"), "model", "expected 'tsai' or 'opencv'"),
        (_mutated(image_size=[320]), "image_size", "expected [width, height]"),
        (_mutated(image_size=[320.5, 240]), "image_size", "expected [width, height]"),
        (_mutated(image_size=[0, 240]), "image_size", "expected [width, height]"),
        (_mutated(image_size=None), "image_size", "expected [width, height]"),
        (_mutated(world2cam_t=[0.0, math.nan, 1.0]), "world2cam_t", "holds NaN or infinity"),
        (_mutated(world2cam_t=[0.0, 1.0]), "world2cam_t", "expected 3 numbers, got shape (2,)"),
        (_mutated(world2cam_t=1.0), "world2cam_t", "expected 3 numbers, got a number"),
        (_mutated(world2cam_t=["0", "0", "1"]), "world2cam_t", "expected 3 numbers"),
        (_mutated(world2cam_t=[0, None, 1]), "world2cam_t", "expected 3 numbers"),
        (_mutated(world2cam_r=ROTATION[:2]), "world2cam_r", "expected a 3 x 3 matrix"),
        (_mutated(world2cam_r=[[1, 0, 0], [0, 1], [0, 0, 1]]), "world2cam_r", "3 x 3 matrix"),
        (_mutated(world2cam_r=np.diag([1.0, 1.0, -1.0]).tolist()), "world2cam_r", "det(R) = -1"),
        (
            _mutated(world2cam_r=(1.001 * np.asarray(ROTATION)).tolist()),
            "world2cam_r",
            "not a rotation matrix",
        ),
        (_mutated(position_m=[math.inf, 0.0, 0.0]), "position_m", "holds NaN or infinity"),
        (_mutated(position_m=[10**400, 0, 0]), "position_m", "holds NaN or infinity"),
        (_mutated(position_m=[0.0, 0.0, 0.0]), "position_m", "from the optical centre"),
        (_mutated(rotation_deg=[0.0, 0.0, 0.0]), "rotation_deg", "disagrees with world2cam_r"),
    ],
)
def test_a_malformed_camera_file_is_refused_by_file_and_key(tmp_path, data, key, expected):
    path = _file(tmp_path, data)
    with pytest.raises(ValueError, match=re.escape(expected)) as err:
        load_camera(path)
    message = str(err.value)
    assert message.startswith(f"{path}: "), message
    assert key in message, message


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("{", "invalid JSON"),
        ("", "invalid JSON"),
        ("[" * 100_000, "invalid JSON"),
    ],
)
def test_a_file_that_is_not_json_is_refused(tmp_path, text, expected):
    path = tmp_path / "cam.json"
    path.write_text(text)
    with pytest.raises(ValueError, match=expected) as err:
        load_camera(path)
    assert str(path) in str(err.value)
    path.write_bytes(b'{"model": "ts\xffai"}')
    with pytest.raises(ValueError, match="not UTF-8") as err:
        load_camera(path)
    assert str(path) in str(err.value)


def test_an_opencv_camera_file_is_read_as_strictly(tmp_path):
    data = camera_to_dict(tsai2opencv(CAMERA).camera)
    assert load_camera(_file(tmp_path, data)).image_size == CAMERA.image_size
    for key, value, expected in [
        ("dist_coeffs", [0.1, 0.2, 0.3], "expected 4 or 5 or 8 numbers"),
        ("dist_coeffs", [0.1, "x", 0, 0, 0], "expected 4 or 5 or 8 numbers"),
        ("camera_matrix", [[-700, 0, 160], [0, 700, 120], [0, 0, 1]], "positive focal"),
        ("camera_matrix", [[700, 0, 160], [0, 700, math.nan], [0, 0, 1]], "NaN or infinity"),
        ("world2cam_t", [math.nan, 0, 0], "NaN or infinity"),
    ]:
        path = _file(tmp_path, {**data, key: value})
        with pytest.raises(ValueError, match=expected) as err:
            load_camera(path)
        assert str(err.value).startswith(f"{path}: {key}")


def test_a_covariance_of_the_wrong_type_is_named(tmp_path):
    save_camera(CAMERA, tmp_path / "c.json", covariance=np.eye(11))
    good = json.loads((tmp_path / "c.json").read_text())
    for matrix in ("eye", None, [[1.0] * 11] * 10, np.full((11, 11), math.nan).tolist()):
        bad = {**good, "covariance": {**good["covariance"], "matrix": matrix}}
        path = _file(tmp_path, bad)
        with pytest.raises(ValueError, match=r"covariance\.matrix") as err:
            load_camera_covariance(path)
        assert str(path) in str(err.value)


def test_a_file_records_what_it_belongs_to(tmp_path):
    for name in ("c.json", "c.yaml"):
        save_camera(CAMERA, tmp_path / name, covariance=np.eye(11), identity=IDENTITY)
    data = json.loads((tmp_path / "c.json").read_text())
    assert list(data)[:2] == list(IDENTITY)  # first, for a person to see
    assert load_camera_identity(tmp_path / "c.json", tuple(IDENTITY)) == IDENTITY
    assert load_camera(tmp_path / "c.json").f == CAMERA.f
    assert "scenario_digest" in (tmp_path / "c.yaml").read_text()
    assert load_camera(tmp_path / "c.yaml").image_size == CAMERA.image_size
    # Keys the file lacks are left out; a key that is not a string is named.
    assert load_camera_identity(tmp_path / "c.json", ("site",)) == {}
    path = _file(tmp_path, {**data, "scenario": 3})
    with pytest.raises(ValueError, match="scenario: expected a non-empty string, got 3"):
        load_camera_identity(path, tuple(IDENTITY))
    with pytest.raises(ValueError, match="a camera file's own keys"):
        save_camera(CAMERA, tmp_path / "d.json", identity={"f_px": "1"})


# -- mutated valid files ---------------------------------------------------------------------
JSON_SCALARS = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**400), 10**400),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8),
)
JSON_VALUES = st.recursive(
    JSON_SCALARS,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=4), inner, max_size=3)
    ),
    max_leaves=12,
)


NUMBERS = st.one_of(
    st.sampled_from([math.nan, math.inf, -math.inf, 0.0, -1.0, 1e308]),
    st.floats(allow_nan=True, allow_infinity=True),
)
"""Numbers that break a camera more often than any float does."""


def _leaves(value: Any, at: tuple = ()) -> list[tuple]:
    """Where ``value`` (nested lists and objects) holds a number: the paths of indices."""
    if isinstance(value, list):
        return [p for k, v in enumerate(value) for p in _leaves(v, (*at, k))]
    if isinstance(value, dict):
        return [p for k, v in value.items() for p in _leaves(v, (*at, k))]
    return [at] if isinstance(value, float | int) and not isinstance(value, bool) else []


def _mutate(data: dict[str, Any], key: str, draw: Any) -> None:
    """Delete ``key``, or give it any JSON value, a value of another shape, or one of its
    numbers changed (types kept: the ranges, the finiteness and the agreement of the pose
    are tested)."""
    action = draw(st.sampled_from(("delete", "any", "number", "shape")))
    leaves = _leaves(data[key])
    if action == "delete":
        del data[key]
    elif action == "any":
        data[key] = draw(JSON_VALUES)
    elif action == "number" and leaves:
        path = draw(st.sampled_from(leaves))
        if not path:
            data[key] = draw(NUMBERS)
        else:
            holder = data[key]
            for k in path[:-1]:
                holder = holder[k]
            holder[path[-1]] = draw(NUMBERS)
    else:
        flat = np.ravel(np.asarray(data[key], dtype=object)).tolist()
        data[key] = flat[: draw(st.integers(0, max(len(flat) - 1, 0)))]


@st.composite
def mutated_files(draw: Any, first: str) -> tuple[dict[str, Any], list[str]]:
    """A valid camera file (Tsai or OpenCV, with covariance and identity) with ``first``
    (where the file has it) and maybe another of its keys mutated (:func:`_mutate`); and
    the keys mutated."""
    tsai = TsaiCamera.from_pose(
        f=draw(st.floats(50.0, 5000.0)),
        cx=draw(st.floats(100.0, 200.0)),
        cy=draw(st.floats(80.0, 160.0)),
        kappa1=draw(st.floats(-1e-6, 1e-6)),
        position=draw(st.lists(st.floats(-50.0, 50.0), min_size=3, max_size=3)),
        rotation_rad=draw(st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3)),
    )
    camera: TsaiCamera | OpenCVCamera = tsai
    if draw(st.booleans()):
        k = [[tsai.f * tsai.sx, 0.0, tsai.cx], [0.0, tsai.f, tsai.cy], [0.0, 0.0, 1.0]]
        dist = draw(st.lists(st.floats(-0.5, 0.5), min_size=5, max_size=5))
        camera = OpenCVCamera(k, dist, tsai.world2cam_r, tsai.world2cam_t, tsai.image_size)
    data = {**IDENTITY, **camera_to_dict(camera)}
    if isinstance(camera, TsaiCamera):
        cov = np.diag(draw(st.lists(st.floats(0.0, 1.0), min_size=11, max_size=11)))
        data["covariance"] = {"parameters": list(CAMERA_PARAMETERS), "matrix": cov.tolist()}
    keys = [first] if first in data else []
    others = sorted(set(data) - {first})
    keys += draw(st.lists(st.sampled_from(others), max_size=1 if keys else 2, unique=True))
    for key in keys:
        _mutate(data, key, draw)
    return data, keys


KEYS = sorted({*IDENTITY, *VALID, "camera_matrix", "dist_coeffs", "covariance"})


@pytest.mark.parametrize("first", KEYS)
@settings(max_examples=15, deadline=None)
@given(data=st.data())
def test_a_mutated_camera_file_reads_or_is_refused_by_file_and_key(first, data):
    data, mutated = data.draw(mutated_files(first))
    with tempfile.TemporaryDirectory() as folder:
        path = _file(Path(folder), data)
        for read, keys in (
            (load_camera, None),
            (load_camera_covariance, ("covariance",)),
            (lambda p: load_camera_identity(p, tuple(IDENTITY)), tuple(IDENTITY)),
        ):
            try:
                got = read(path)
            except ValueError as exc:
                message = str(exc)
                assert message.startswith(f"{path}: "), message
                # A changed model asks for the other model's keys: any key may be named.
                named = [k for k in mutated if keys is None or k in keys]
                if named and "model" not in mutated:
                    assert any(k in message for k in named), (mutated, message)
                continue
            if read is load_camera:
                _reads_as_written(got, data)


def _reads_as_written(camera: TsaiCamera | OpenCVCamera, data: dict[str, Any]) -> None:
    """What reads is a camera with finite parameters and a proper rotation, and every value
    the file gives, the derived ones included, is the camera's."""
    r = camera.world2cam_r
    assert np.allclose(r @ r.T, np.eye(3), atol=1e-9)
    assert np.linalg.det(r) > 0
    assert np.isfinite(camera.world2cam_t).all()
    if isinstance(camera, TsaiCamera):
        assert camera.f > 0
        assert camera.sx > 0
        assert all(math.isfinite(v) for v in (camera.f, camera.cx, camera.cy, camera.kappa1))
    for key, value in camera_to_dict(camera).items():
        if key not in data:
            continue
        if key == "rotation_deg":  # angles about a gimbal lock are not unique
            assert np.allclose(euler2matrix(np.radians(data[key])), r, atol=1e-6)
        elif key == "model":
            assert data[key] == value
        elif key == "dist_coeffs":  # four coefficients read as five, k3 = 0
            assert np.allclose(np.pad(data[key], (0, len(value) - len(data[key]))), value)
        else:
            assert np.allclose(data[key], value, rtol=1e-12, atol=1e-6), key
