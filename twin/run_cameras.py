"""The cameras a run wrote (``DIR/cameras/``), read back for ``twin check``: the latest
calibration of each camera, with its covariance where the file holds one.

``twin run`` writes each calibration as ``NAME_visitK.json`` (with ``.yaml`` and
``.camera_info.yaml`` beside it, which are not read here); ``twin check`` writes a camera
it re-posed as ``NAME_check.json``, which counts as later than any visit.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from calib.camera import TsaiCamera
from calib.io.camera_files import load_camera, load_camera_covariance
from twin.scenario.schema import Scenario

CAMERA_FILE = re.compile(r"^(?P<name>[A-Za-z][A-Za-z0-9_]*?)_(?:visit(?P<visit>\d+)|check)\.json$")
"""The JSON camera files of a run (``NAME_visitK.json``) or a check (``NAME_check.json``)."""

CHECKED = 10**9
"""The order of a check's re-posed camera among a camera's files: after every visit."""


class CamerasFolderError(ValueError):
    """The cameras folder cannot be checked: the message names the folder or the file."""


@dataclass(frozen=True)
class CalibratedCamera:
    """A camera as its latest calibration left it.

    Attributes:
        name: the camera's name. path: its JSON file.
        visit: the calibration's visit number (None for a check's re-posed camera).
        camera: the model, pose in W.
        covariance: (11, 11) its covariance (:mod:`calib.camera_covariance`), or None
            when the file holds none.
    """

    name: str
    path: Path
    visit: int | None
    camera: TsaiCamera
    covariance: NDArray[np.float64] | None


def latest_cameras(folder: str | Path, scenario: Scenario) -> dict[str, CalibratedCamera]:
    """The latest calibration of each camera in ``folder``, by name, in the scenario's
    camera order.

    Raises:
        CamerasFolderError: the folder is missing or holds no camera file; a JSON file is
            not named as a run names its cameras; a camera is not in the scenario; a file
            cannot be read or is not a Tsai camera. The message names the folder or file.
    """
    path = Path(folder)
    expected = "the cameras/ folder a `twin run` wrote"
    if not path.exists():
        raise CamerasFolderError(f"--cameras {path}: no such folder; expected {expected}")
    if not path.is_dir():
        raise CamerasFolderError(f"--cameras {path}: is a file; expected {expected}")
    names = [c.name for c in scenario.cameras]
    found: dict[str, tuple[int, Path]] = {}
    for file in sorted(path.glob("*.json")):
        match = CAMERA_FILE.match(file.name)
        if match is None:
            raise CamerasFolderError(
                f"{file}: not a camera file of a run; expected NAME_visitK.json (as `twin "
                "run` writes) or NAME_check.json (as `twin check` writes)"
            )
        name = match["name"]
        if name not in names:
            where = f" ({scenario.source})" if scenario.source else ""
            raise CamerasFolderError(
                f"{file}: camera {name!r} is not in scenario {scenario.name!r}{where}; its "
                f"cameras: {', '.join(names)}"
            )
        order = CHECKED if match["visit"] is None else int(match["visit"])
        if name not in found or order > found[name][0]:
            found[name] = (order, file)
    if not found:
        raise CamerasFolderError(
            f"--cameras {path}: holds no camera file (NAME_visitK.json); expected {expected}"
        )
    out = {}
    for name in names:
        if name in found:
            order, file = found[name]
            out[name] = _read(name, file, None if order == CHECKED else order)
    return out


def _read(name: str, file: Path, visit: int | None) -> CalibratedCamera:
    try:
        camera = load_camera(file)
        covariance = load_camera_covariance(file)
    except (OSError, ValueError) as exc:
        text = str(exc)
        raise CamerasFolderError(text if str(file) in text else f"{file}: {text}") from None
    if not isinstance(camera, TsaiCamera):
        raise CamerasFolderError(
            f"{file}: an OpenCV camera; the check re-poses Tsai's model (as `twin run` "
            "calibrates it)"
        )
    return CalibratedCamera(name, file, visit, camera, covariance)
