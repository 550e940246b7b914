"""Camera files: our JSON, OpenCV FileStorage YAML, and ROS ``camera_info`` YAML.

The format follows the file name:

* ``*.json``: the full model (Tsai or OpenCV) with its pose, exactly round-tripped, and
  optionally the camera's covariance (``covariance``: ``parameters``, the names of
  :data:`calib.camera_covariance.CAMERA_PARAMETERS`, and ``matrix``, 11 x 11; read with
  :func:`load_camera_covariance`);
* ``*.camera_info.yaml``: ROS ``sensor_msgs/CameraInfo`` (intrinsics only, no pose);
* ``*.yaml`` / ``*.yml``: OpenCV FileStorage with ``camera_matrix``,
  ``distortion_coefficients`` and the world-to-camera pose.

A Tsai camera written to an OpenCV or ROS file is first converted to OpenCV's model with
:func:`calib.opencv_camera.tsai2opencv`; reading such a file gives an OpenCVCamera.

A JSON or OpenCV file may also record what it belongs to (``identity``: a scenario's name
and digest, say), as strings under keys of their own (:func:`load_camera_identity`).

A JSON camera is read strictly: every key it needs present, every number a finite number
(not a string, null or true), every matrix and vector of its shape, the rotation a proper
rotation matrix, the focal length and scale positive, and the redundant ``position_m`` and
``rotation_deg`` (written for people to read) in agreement with the pose. Each error names
the file and the key.
"""

from __future__ import annotations

import errno
import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from calib.camera import TsaiCamera
from calib.camera_covariance import CAMERA_PARAMETERS, N_CAMERA, check_camera_covariance
from calib.checks import MAX_IMAGE_SIDE_PX
from calib.io.atomic import atomic_file
from calib.io.text import NotText, read_text, yaml_load
from calib.opencv_camera import OpenCVCamera, tsai2opencv
from calib.rotation import euler2matrix

Camera = TsaiCamera | OpenCVCamera

ROTATION_TOLERANCE = 1e-9
"""Largest entry of ``R R^T - I`` a rotation matrix may have (what :class:`TsaiCamera`
accepts; a file written here holds its rotation to the bit)."""

AGREEMENT_M = 1e-6
"""Most a coordinate of ``position_m`` may differ from the optical centre the pose gives,
m."""

AGREEMENT_ROTATION = 1e-6
"""Largest entry by which the rotation ``rotation_deg`` gives may differ from
``world2cam_r``."""

DIST_COEFFS_SIZES = (4, 5, 8)
"""The lengths of an OpenCV camera's distortion coefficients."""


def camera_format(path: str | Path) -> str:
    """ "json", "ros" or "opencv" from the file name; ValueError for anything else."""
    name = Path(path).name.lower()
    if name.endswith(".json"):
        return "json"
    if name.endswith((".camera_info.yaml", ".camera_info.yml")):
        return "ros"
    if name.endswith((".yaml", ".yml")):
        return "opencv"
    raise ValueError(
        f"{path}: unknown camera file type; use .json, .yaml (OpenCV) or .camera_info.yaml (ROS)"
    )


def _as_opencv(camera: Camera) -> tuple[OpenCVCamera, float | None]:
    if isinstance(camera, OpenCVCamera):
        return camera, None
    conv = tsai2opencv(camera)
    return conv.camera, conv.max_error_px


# -- JSON ----------------------------------------------------------------------------------
def camera_to_dict(camera: Camera) -> dict[str, Any]:
    """A JSON-ready description of a camera (SI units)."""
    common = {
        "image_size": list(camera.image_size),
        "world2cam_r": camera.world2cam_r.tolist(),
        "world2cam_t": camera.world2cam_t.tolist(),
        "position_m": camera.position.tolist(),
    }
    if isinstance(camera, TsaiCamera):
        return {
            "model": "tsai",
            "f_px": camera.f,
            "cx": camera.cx,
            "cy": camera.cy,
            "sx": camera.sx,
            "kappa1_px": camera.kappa1,
            "rotation_deg": np.degrees(camera.rotation_rad).tolist(),
            **common,
        }
    return {
        "model": "opencv",
        "camera_matrix": camera.camera_matrix.tolist(),
        "dist_coeffs": camera.dist_coeffs.tolist(),
        **common,
    }


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _kind(value: Any) -> str:
    """How a JSON value is named in an error: its text, cut short."""
    try:
        text = json.dumps(value, default=repr)
    except (ValueError, RecursionError):
        text = f"a deeply nested {type(value).__name__}"
    return text if len(text) <= 60 else text[:57] + "..."


def _field(data: dict[str, Any], key: str, source: str) -> Any:
    if key not in data:
        raise ValueError(f"{source}: missing key {key!r}")
    return data[key]


def _nested_floats(value: Any) -> Any:
    """``value`` with every number as a float (a whole number too large for a float as
    infinity); ValueError where it holds anything but numbers and lists."""
    if _is_number(value):
        try:
            return float(value)
        except OverflowError:
            return math.inf
    if isinstance(value, list):
        return [_nested_floats(v) for v in value]
    raise ValueError(value)


def _array(
    value: Any, key: str, shape: tuple[int, ...], source: str, expected: str = ""
) -> np.ndarray:
    """``value`` (the file's ``key``) as a float array of ``shape`` with finite entries;
    ``expected`` says what it should be (default: from the shape)."""
    if not expected:
        what = " x ".join(str(n) for n in shape)
        expected = {0: "a number", 1: f"{what} numbers", 2: f"a {what} matrix"}[len(shape)]
    expected = f"expected {expected}"
    try:
        arr = np.array(_nested_floats(value), dtype=float)
    except (ValueError, RecursionError):
        raise ValueError(f"{source}: {key}: {expected}, got {_kind(value)}") from None
    if arr.shape != shape:
        got = "a number" if arr.ndim == 0 else f"shape {arr.shape}"
        raise ValueError(f"{source}: {key}: {expected}, got {got}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{source}: {key}: holds NaN or infinity; {expected}, each finite")
    return arr


def _number(data: dict[str, Any], key: str, source: str, *, positive: bool = False) -> float:
    """The file's ``key`` as a finite number (above 0 where ``positive``)."""
    value = _field(data, key, source)
    number = _nested_floats(value) if _is_number(value) else math.nan
    if not (_is_number(value) and math.isfinite(number) and (number > 0 or not positive)):
        expected = "a positive finite number" if positive else "a finite number"
        raise ValueError(f"{source}: {key}: expected {expected}, got {_kind(value)}")
    return float(number)


def _image_size(data: dict[str, Any], source: str) -> tuple[int, int]:
    value = _field(data, "image_size", source)
    ok = (
        isinstance(value, list)
        and len(value) == 2
        and all(isinstance(v, int) and not isinstance(v, bool) for v in value)
        and all(0 < v <= MAX_IMAGE_SIDE_PX for v in value)
    )
    if not ok:
        raise ValueError(
            f"{source}: image_size: expected [width, height], two whole numbers of pixels "
            f"from 1 to {MAX_IMAGE_SIDE_PX}, got {_kind(value)}"
        )
    return int(value[0]), int(value[1])


def _rotation(data: dict[str, Any], source: str) -> np.ndarray:
    r = _array(_field(data, "world2cam_r", source), "world2cam_r", (3, 3), source)
    with np.errstate(over="ignore", invalid="ignore"):  # entries near the largest float
        off = float(np.abs(r @ r.T - np.eye(3)).max())
    if not off <= ROTATION_TOLERANCE or np.linalg.det(r) < 0:
        raise ValueError(
            f"{source}: world2cam_r: not a rotation matrix (R R^T differs from the identity "
            f"by {off:.3g}, det(R) = {np.linalg.det(r):.6g}); expected an orthonormal matrix "
            f"with determinant +1, to {ROTATION_TOLERANCE:g}"
        )
    return r


def _agreeing(
    data: dict[str, Any], r: np.ndarray, t: np.ndarray, source: str, *, tsai: bool
) -> None:
    """The redundant ``position_m`` and (Tsai) ``rotation_deg``, where present, agree with
    the pose: an edit of one of them alone would be silently ignored."""
    if "position_m" in data:
        position = _array(data["position_m"], "position_m", (3,), source)
        with np.errstate(over="ignore", invalid="ignore"):  # a translation near the largest float
            centre = -r.T @ t
            off = float(np.abs(position - centre).max())
        if not off <= AGREEMENT_M:
            raise ValueError(
                f"{source}: position_m {position.tolist()} differs by {off:.3g} m from the "
                f"optical centre that world2cam_r and world2cam_t give ({centre.tolist()}); "
                "it is derived from them: correct it, or the pose, or leave it out"
            )
    if tsai and "rotation_deg" in data:
        angles = _array(data["rotation_deg"], "rotation_deg", (3,), source)
        off = float(np.abs(euler2matrix(np.radians(angles)) - r).max())
        if not off <= AGREEMENT_ROTATION:
            raise ValueError(
                f"{source}: rotation_deg {angles.tolist()} disagrees with world2cam_r (by "
                f"{off:.3g} in a matrix entry); it is derived from it: correct it, or the "
                "matrix, or leave it out"
            )


def camera_from_dict(data: Any, source: str = "camera") -> Camera:
    """Inverse of :func:`camera_to_dict`.

    Raises:
        ValueError: ``data`` is not an object, a key is missing, a value is of the wrong
            type or shape, not finite or out of its range, the rotation is not one, or the
            redundant ``position_m`` or ``rotation_deg`` disagrees with the pose. The
            message names ``source`` and the key.
    """
    if not isinstance(data, dict):
        raise ValueError(f"{source}: expected a JSON object (a camera), got {_kind(data)}")
    model = _field(data, "model", source)
    if model not in ("tsai", "opencv"):
        raise ValueError(f"{source}: model: expected 'tsai' or 'opencv', got {_kind(model)}")
    size = _image_size(data, source)
    r = _rotation(data, source)
    t = _array(_field(data, "world2cam_t", source), "world2cam_t", (3,), source)
    _agreeing(data, r, t, source, tsai=model == "tsai")
    if model == "tsai":
        f = _number(data, "f_px", source, positive=True)
        cx = _number(data, "cx", source)
        cy = _number(data, "cy", source)
        kappa1 = _number(data, "kappa1_px", source)
        sx = _number(data, "sx", source, positive=True)
        return TsaiCamera(f, cx, cy, kappa1, sx, r, t, size)
    k = _array(_field(data, "camera_matrix", source), "camera_matrix", (3, 3), source)
    if k[0, 0] <= 0 or k[1, 1] <= 0:
        raise ValueError(
            f"{source}: camera_matrix: expected positive focal lengths fx and fy, got "
            f"{k[0, 0]:g} and {k[1, 1]:g}"
        )
    raw = _field(data, "dist_coeffs", source)
    n = len(raw) if isinstance(raw, list) and len(raw) in DIST_COEFFS_SIZES else 5
    sizes = " or ".join(str(m) for m in DIST_COEFFS_SIZES)
    d = _array(raw, "dist_coeffs", (n,), source, f"{sizes} numbers")
    return OpenCVCamera(k, d, r, t, size)


# -- OpenCV FileStorage ----------------------------------------------------------------------
def _write_opencv_yaml(path: Path, camera: Camera, identity: Mapping[str, str]) -> None:
    cv_cam, conv_err = _as_opencv(camera)
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    if not fs.isOpened():
        raise OSError(errno.EIO, "OpenCV cannot open the file for writing", str(path))
    try:
        for key, value in identity.items():
            fs.write(key, str(value))
        fs.write("image_width", int(cv_cam.image_size[0]))
        fs.write("image_height", int(cv_cam.image_size[1]))
        fs.write("camera_matrix", np.array(cv_cam.camera_matrix))
        fs.write("distortion_coefficients", np.array(cv_cam.dist_coeffs).reshape(1, -1))
        fs.write("world2cam_rotation", np.array(cv_cam.world2cam_r))
        fs.write("world2cam_translation", np.array(cv_cam.world2cam_t).reshape(3, 1))
        if conv_err is not None:
            fs.write("tsai_conversion_max_error_px", float(conv_err))
    finally:
        fs.release()


def _read_opencv_yaml(path: Path) -> OpenCVCamera:
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    try:
        if not fs.isOpened():
            raise ValueError(f"{path}: OpenCV cannot open this file")

        def mat(key: str) -> np.ndarray:
            node = fs.getNode(key)
            if node.empty():
                raise ValueError(f"{path}: missing key {key!r}")
            return node.mat()

        size = (int(fs.getNode("image_width").real()), int(fs.getNode("image_height").real()))
        k, d = mat("camera_matrix"), mat("distortion_coefficients")
        r_node, t_node = fs.getNode("world2cam_rotation"), fs.getNode("world2cam_translation")
        r = np.eye(3) if r_node.empty() else r_node.mat()
        t = np.zeros(3) if t_node.empty() else t_node.mat().ravel()
    finally:
        fs.release()
    return OpenCVCamera(k, d.ravel(), r, t, size)


# -- ROS camera_info -------------------------------------------------------------------------
def _ros_matrix(rows: int, cols: int, data: np.ndarray) -> dict[str, Any]:
    return {"rows": rows, "cols": cols, "data": [float(v) for v in np.ravel(data)]}


def _write_ros_yaml(path: Path, camera: Camera, name: str) -> None:
    cv_cam, _ = _as_opencv(camera)
    k = cv_cam.camera_matrix
    d = cv_cam.dist_coeffs
    p = np.hstack([k, np.zeros((3, 1))])
    doc = {
        "image_width": int(cv_cam.image_size[0]),
        "image_height": int(cv_cam.image_size[1]),
        "camera_name": name,
        "camera_matrix": _ros_matrix(3, 3, k),
        "distortion_model": "rational_polynomial" if d.size == 8 else "plumb_bob",
        "distortion_coefficients": _ros_matrix(1, d.size, d),
        "rectification_matrix": _ros_matrix(3, 3, np.eye(3)),
        "projection_matrix": _ros_matrix(3, 4, p),
    }
    path.write_text(yaml.safe_dump(doc, sort_keys=False))


def _read_ros_yaml(path: Path) -> OpenCVCamera:
    try:
        doc = yaml_load(read_text(path))
        size = (int(doc["image_width"]), int(doc["image_height"]))
        k = np.asarray(doc["camera_matrix"]["data"], dtype=float).reshape(3, 3)
        d = np.asarray(doc["distortion_coefficients"]["data"], dtype=float)
    except KeyError as exc:
        raise ValueError(f"{path}: missing key {exc.args[0]!r} of a ROS camera_info") from None
    except (TypeError, NotText, yaml.YAMLError) as exc:
        raise ValueError(f"{path}: not a ROS camera_info YAML file ({exc})") from None
    return OpenCVCamera(k, d, np.eye(3), np.zeros(3), size)


# -- dispatch ------------------------------------------------------------------------------
def save_camera(
    camera: Camera,
    path: str | Path,
    name: str = "camera",
    covariance: np.ndarray | None = None,
    identity: Mapping[str, str] | None = None,
) -> None:
    """Write a camera; the format follows the file name (see the module docstring).

    Missing folders are created. The file is written whole or not at all
    (:func:`calib.io.atomic.atomic_file`).

    Args:
        camera: the camera. path: the file. name: the camera's name (ROS files).
        covariance: (11, 11) the camera's covariance in the terms of
            :data:`calib.camera_covariance.CAMERA_PARAMETERS`, written into a JSON file
            (a Tsai camera's only; the other formats have no place for it).
        identity: what the camera belongs to, strings by key (a scenario's name and
            digest), written first into a JSON file and into an OpenCV file (a ROS
            camera_info has no place for it); read back with :func:`load_camera_identity`.

    Raises:
        ValueError: an unknown file type, a covariance that is not an 11 x 11 symmetric
            matrix, or an identity key that a camera's own keys use.
        OSError: the file cannot be written.
    """
    path = Path(path)
    fmt = camera_format(path)
    data = camera_to_dict(camera)
    ids = dict(identity or {})
    clash = sorted(set(ids) & {*data, "covariance"})
    if clash:
        raise ValueError(f"identity keys {clash} are a camera file's own keys")
    if covariance is not None and fmt == "json":
        data["covariance"] = covariance_to_dict(covariance)
    data = {**ids, **data}
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_file(path) as tmp:
        if fmt == "json":
            tmp.write_text(json.dumps(data, indent=2) + "\n")
        elif fmt == "ros":
            _write_ros_yaml(tmp, camera, name)
        else:
            _write_opencv_yaml(tmp, camera, ids)


def covariance_to_dict(covariance: np.ndarray) -> dict[str, Any]:
    """A camera's (11, 11) covariance as the JSON file holds it."""
    cov = check_camera_covariance(covariance)
    return {"parameters": list(CAMERA_PARAMETERS), "matrix": cov.tolist()}


def _read_json(path: Path) -> Any:
    """The JSON value a file holds; ValueError naming the file when it is not UTF-8 JSON.
    (Python's reader takes NaN and Infinity: the camera's checks refuse them by key.)"""
    try:
        return json.loads(read_text(path))
    except NotText as exc:
        raise ValueError(f"{path}: not a JSON camera file: {exc}") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: invalid JSON ({exc})") from None
    except RecursionError:
        raise ValueError(f"{path}: invalid JSON (nested too deep)") from None


def load_camera_covariance(path: str | Path) -> np.ndarray | None:
    """The (11, 11) covariance a camera JSON file holds (see :func:`save_camera`), or None
    when it holds none (or the file is not JSON).

    Raises:
        ValueError: the file is not valid JSON, or its covariance names other parameters
            or is not an 11 x 11 symmetric matrix of finite numbers; the message names the
            file and the key.
    """
    path = Path(path)
    if camera_format(path) != "json":
        return None
    data = _read_json(path)
    block = data.get("covariance") if isinstance(data, dict) else None
    if block is None:
        return None
    if not isinstance(block, dict) or "matrix" not in block:
        raise ValueError(f"{path}: covariance must be an object with parameters and matrix")
    names = block.get("parameters")
    if names != list(CAMERA_PARAMETERS):
        raise ValueError(
            f"{path}: covariance.parameters must be {list(CAMERA_PARAMETERS)}, got {names!r}"
        )
    matrix = _array(block["matrix"], "covariance.matrix", (N_CAMERA, N_CAMERA), str(path))
    try:
        return check_camera_covariance(matrix, f"{path}: covariance.matrix")
    except ValueError as exc:
        raise ValueError(str(exc) if str(path) in str(exc) else f"{path}: {exc}") from None


def load_camera_identity(path: str | Path, keys: tuple[str, ...]) -> dict[str, str]:
    """What a camera JSON file records it belongs to (:func:`save_camera`'s ``identity``):
    the string each of ``keys`` holds, the keys it lacks left out ({} for a file of
    another format).

    Raises:
        ValueError: the file is not valid JSON or not an object, or one of ``keys`` holds
            anything but a non-empty string; the message names the file and the key.
    """
    path = Path(path)
    if camera_format(path) != "json":
        return {}
    data = _read_json(path)
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a JSON object (a camera), got {_kind(data)}")
    out = {}
    for key in keys:
        if key not in data:
            continue
        value = data[key]
        if not isinstance(value, str) or not value:
            raise ValueError(f"{path}: {key}: expected a non-empty string, got {_kind(value)}")
        out[key] = value
    return out


def load_camera(path: str | Path) -> Camera:
    """Read a camera written by :func:`save_camera` (or by OpenCV / ROS tools).

    Raises:
        ValueError: an unknown file type, or a file that is not a camera of its format;
            for JSON, every problem of :func:`camera_from_dict`, with the file and key.
        OSError: the file cannot be read.
    """
    path = Path(path)
    fmt = camera_format(path)
    if fmt == "json":
        return camera_from_dict(_read_json(path), str(path))
    if fmt == "ros":
        return _read_ros_yaml(path)
    return _read_opencv_yaml(path)
