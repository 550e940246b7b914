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
"""

from __future__ import annotations

import errno
import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from calib.camera import TsaiCamera
from calib.camera_covariance import CAMERA_PARAMETERS, check_camera_covariance
from calib.io.atomic import atomic_file
from calib.io.text import NotText, read_text, yaml_load
from calib.opencv_camera import OpenCVCamera, tsai2opencv

Camera = TsaiCamera | OpenCVCamera


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


def camera_from_dict(data: dict[str, Any], source: str = "camera") -> Camera:
    """Inverse of :func:`camera_to_dict`; errors name the source and the missing key."""
    try:
        model = data["model"]
        size = tuple(data["image_size"])
        r = np.asarray(data["world2cam_r"], dtype=float)
        t = np.asarray(data["world2cam_t"], dtype=float)
        if model == "tsai":
            return TsaiCamera(
                data["f_px"], data["cx"], data["cy"], data["kappa1_px"], data["sx"], r, t, size
            )
        if model == "opencv":
            return OpenCVCamera(data["camera_matrix"], data["dist_coeffs"], r, t, size)
    except KeyError as exc:
        raise ValueError(f"{source}: missing key {exc.args[0]!r}") from None
    raise ValueError(f"{source}: unknown model {model!r}; expected 'tsai' or 'opencv'")


# -- OpenCV FileStorage ----------------------------------------------------------------------
def _write_opencv_yaml(path: Path, camera: Camera) -> None:
    cv_cam, conv_err = _as_opencv(camera)
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    if not fs.isOpened():
        raise OSError(errno.EIO, "OpenCV cannot open the file for writing", str(path))
    try:
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
) -> None:
    """Write a camera; the format follows the file name (see the module docstring).

    Missing folders are created. The file is written whole or not at all
    (:func:`calib.io.atomic.atomic_file`).

    Args:
        camera: the camera. path: the file. name: the camera's name (ROS files).
        covariance: (11, 11) the camera's covariance in the terms of
            :data:`calib.camera_covariance.CAMERA_PARAMETERS`, written into a JSON file
            (a Tsai camera's only; the other formats have no place for it).

    Raises:
        ValueError: an unknown file type, or a covariance that is not an 11 x 11 symmetric
            matrix. OSError: the file cannot be written.
    """
    path = Path(path)
    fmt = camera_format(path)
    data = camera_to_dict(camera)
    if covariance is not None and fmt == "json":
        data["covariance"] = covariance_to_dict(covariance)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_file(path) as tmp:
        if fmt == "json":
            tmp.write_text(json.dumps(data, indent=2) + "\n")
        elif fmt == "ros":
            _write_ros_yaml(tmp, camera, name)
        else:
            _write_opencv_yaml(tmp, camera)


def covariance_to_dict(covariance: np.ndarray) -> dict[str, Any]:
    """A camera's (11, 11) covariance as the JSON file holds it."""
    cov = check_camera_covariance(covariance)
    return {"parameters": list(CAMERA_PARAMETERS), "matrix": cov.tolist()}


def load_camera_covariance(path: str | Path) -> np.ndarray | None:
    """The (11, 11) covariance a camera JSON file holds (see :func:`save_camera`), or None
    when it holds none (or the file is not JSON).

    Raises:
        ValueError: the file is not valid JSON, or its covariance names other parameters
            or is not an 11 x 11 symmetric matrix of finite numbers; the message names the
            file.
    """
    path = Path(path)
    if camera_format(path) != "json":
        return None
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: invalid JSON ({exc})") from None
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
    try:
        return check_camera_covariance(block["matrix"], f"{path}: covariance.matrix")
    except (TypeError, ValueError) as exc:
        raise ValueError(str(exc) if str(path) in str(exc) else f"{path}: {exc}") from None


def load_camera(path: str | Path) -> Camera:
    """Read a camera written by :func:`save_camera` (or by OpenCV / ROS tools)."""
    path = Path(path)
    fmt = camera_format(path)
    if fmt == "json":
        try:
            data = json.loads(path.read_text())
        except json.JSONDecodeError as exc:
            raise ValueError(f"{path}: invalid JSON ({exc})") from None
        return camera_from_dict(data, str(path))
    if fmt == "ros":
        return _read_ros_yaml(path)
    return _read_opencv_yaml(path)
