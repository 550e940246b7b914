"""The cameras a run wrote (``DIR/cameras/``), read back for ``twin check``: the latest
calibration of each camera, with its covariance where the file holds one.

``twin run`` writes each calibration as ``NAME_visitK.json`` (with ``.yaml`` and
``.camera_info.yaml`` beside it, which are not read here); ``twin check`` writes a camera
it re-posed as ``NAME_check.json``, which counts as later than any visit.

Each file records the scenario it was calibrated in (:func:`camera_identity`). A camera
is refused, by its file, when it belongs to another scenario (another name, or the same
name with another digest), or, for files written before the record, when it lies outside
the scenario's space or its image size is not the scenario camera's: a calibration holds
only in the world frame and the site it was made in.
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from calib.camera import TsaiCamera
from calib.io.camera_files import load_camera, load_camera_covariance, load_camera_identity
from twin.scenario.digest import DIGEST_LENGTH, scenario_identity
from twin.scenario.schema import CameraConfig, Scenario

CAMERA_FILE = re.compile(r"^(?P<name>[A-Za-z][A-Za-z0-9_]*?)_(?:visit(?P<visit>\d+)|check)\.json$")
"""The JSON camera files of a run (``NAME_visitK.json``) or a check (``NAME_check.json``)."""

CHECKED = 10**9
"""The order of a check's re-posed camera among a camera's files: after every visit."""


IDENTITY_KEYS = ("scenario", "scenario_digest", "site_digest")
"""What a camera file records of its scenario (:func:`camera_identity`)."""

SITE: dict[str, Any] = {
    "space": {"origin", "size", "floor_z", "wall_thickness", "obstacles", "floor_patches"},
    "cameras": {"__all__": set(CameraConfig.model_fields) - {"sensor", "led_centroid_px"}},
    "robots": {"parent"},
    "site": True,
}
"""What of a scenario a calibration depends on, the fields its site digest covers: the
space (not its lighting), the cameras' placement, intrinsics and image size (not the
twin's sensor and centroid noise), the parent, whose first station is W, and the map a
planned site came from. Not the seed, noise, faults, people, the campaign's settings, the
route or the visits: ``--seed``, ``--no-noise``, a camera moved in ``[faults]`` or a check
from another station change those, not what a camera file is calibrated in."""

SPACE_MARGIN_M = 0.5
"""How far outside the space's walls a calibrated camera of a file without its scenario's
record may lie, m: a calibration's position error is centimetres, another site's camera
lies metres off."""


class CamerasFolderError(ValueError):
    """The cameras folder cannot be checked: the message names the folder or the file."""


def site_digest(scenario: Scenario) -> str:
    """The digest (as :func:`twin.scenario.digest.scenario_digest` computes one) of the
    scenario's :data:`SITE`."""
    text = scenario.model_dump_json(include=SITE)
    return hashlib.sha256(text.encode()).hexdigest()[:DIGEST_LENGTH]


def camera_identity(scenario: Scenario) -> dict[str, str]:
    """What a camera file records of the scenario it was calibrated in:
    :func:`twin.scenario.digest.scenario_identity` (``scenario``, ``scenario_digest``)
    and ``site_digest`` (:func:`site_digest`), which a check compares when the full
    digests differ."""
    return {**scenario_identity(scenario), "site_digest": site_digest(scenario)}


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
            out[name] = _read(name, file, None if order == CHECKED else order, scenario)
    return out


def _read(name: str, file: Path, visit: int | None, scenario: Scenario) -> CalibratedCamera:
    try:
        camera = load_camera(file)
        covariance = load_camera_covariance(file)
        record = load_camera_identity(file, IDENTITY_KEYS)
    except (OSError, ValueError) as exc:
        text = str(exc)
        raise CamerasFolderError(text if str(file) in text else f"{file}: {text}") from None
    if not isinstance(camera, TsaiCamera):
        raise CamerasFolderError(
            f"{file}: an OpenCV camera; the check re-poses Tsai's model (as `twin run` "
            "calibrates it)"
        )
    _same_scenario(file, record, scenario)
    _same_site(file, name, camera, scenario, "scenario_digest" in record)
    return CalibratedCamera(name, file, visit, camera, covariance)


def _where(scenario: Scenario) -> str:
    return f"scenario {scenario.name!r}" + (f" ({scenario.source})" if scenario.source else "")


def _same_scenario(file: Path, record: dict[str, str], scenario: Scenario) -> None:
    """Refuse a file that records another scenario: another name, or the same name with
    another digest (of the site too, where the file records it)."""
    said = record.get("scenario")
    if said is not None and said != scenario.name:
        raise CamerasFolderError(
            f"{file}: calibrated in scenario {said!r}, not in {_where(scenario)}: a "
            f"calibration holds only in its own scenario's world frame; check it with {said!r}"
        )
    digest = record.get("scenario_digest")
    ours = camera_identity(scenario)
    if digest is None or digest == ours["scenario_digest"]:
        return
    site = record.get("site_digest")
    if site is not None and site == ours["site_digest"]:
        return  # the same site: only the twin's settings or the procedure differ
    then = f"digest {digest}" + (f", site {site}" if site else "")
    now = f"digest {ours['scenario_digest']}, site {ours['site_digest']}"
    raise CamerasFolderError(
        f"{file}: calibrated in scenario {scenario.name!r} as it was then ({then}); "
        f"{_where(scenario)} is another now ({now}): its site changed (the space, the "
        "cameras, or the parent's first station, which is W); check with the scenario the "
        "calibration was made in"
    )


def _same_site(
    file: Path, name: str, camera: TsaiCamera, scenario: Scenario, recorded: bool
) -> None:
    """Refuse a camera whose image size is not the scenario camera's, or that lies outside
    the scenario's space (by :data:`SPACE_MARGIN_M`)."""
    why = "" if recorded else " (the file records no scenario)"
    planned = tuple(scenario.camera(name).image_size)
    if tuple(camera.image_size) != planned:
        w, h = camera.image_size
        raise CamerasFolderError(
            f"{file}: image_size {w} x {h}, but camera {name!r} of {_where(scenario)} takes "
            f"{planned[0]} x {planned[1]} images{why}: a calibration of another camera"
        )
    m = SPACE_MARGIN_M
    ranges = (scenario.space.x_range, scenario.space.y_range, scenario.space.z_range)
    position = camera.position
    if all(lo - m <= v <= hi + m for v, (lo, hi) in zip(position, ranges, strict=True)):
        return
    x, y, z = position
    (x0, x1), (y0, y1), (z0, z1) = ranges
    raise CamerasFolderError(
        f"{file}: the camera lies at ({x:.2f}, {y:.2f}, {z:.2f}) m{why}, outside the space "
        f"of {_where(scenario)}: x {x0:g} to {x1:g}, y {y0:g} to {y1:g}, z {z0:g} to {z1:g} "
        f"m, and {m:g} m more for a calibration's error; a calibration of another space or "
        "world frame"
    )
