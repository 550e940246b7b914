"""What ``twin check`` writes: ``check.json`` and the re-posed cameras' files.

``check.json`` holds, under ``cameras``, one object per checked camera:

- ``moved`` (the chi-square test's verdict), ``chi2``, ``dof``, ``threshold``,
  ``p_value``, ``false_alarm_rate``;
- ``shift_mm`` and ``turn_deg`` (magnitudes), ``shift_vector_mm`` (the optical centre's
  shift in W) and ``turn_vector_deg`` (a rotation vector about the calibrated camera's own
  x, y, z axes), with ``shift_std_mm`` and ``turn_std_deg`` (their components' standard
  deviations), from the re-pose (:mod:`calib.pose_change`'s convention);
- ``stops``, ``points``, ``station`` (where the data were taken), ``calibration`` (the
  file checked), ``calibration_covariance`` (whether it held one);
- ``reposed``: the re-posed camera (:func:`calib.io.camera_files.camera_to_dict`) where it
  moved, else null; ``files``: its camera files;
- in the twin, ``truth``: how the camera truly moved from its calibration and how far the
  re-posed camera lies from the truth.

``unchecked`` names each camera that was not checked, and why.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from calib.camera import TsaiCamera
from calib.io.camera_files import camera_from_dict, camera_to_dict, save_camera
from calib.pose_change import pose_change
from calib.rotation import rotation_angle_between
from twin.campaign.check import CameraCheck, CheckOutcome
from twin.run.run_cameras import CalibratedCamera

CAMERA_SUFFIXES = (".json", ".yaml", ".camera_info.yaml")
"""The files of a re-posed camera, as ``twin run`` writes each calibration's."""


def _mm(v: Any) -> list[float]:
    return [float(x) for x in 1e3 * np.asarray(v, dtype=float)]


def _deg(v: Any) -> list[float]:
    return [float(x) for x in np.degrees(np.asarray(v, dtype=float))]


def camera_entry(
    check: CameraCheck,
    calibrated: CalibratedCamera,
    station: str,
    truth: TsaiCamera | None,
    files: list[str],
) -> dict[str, Any]:
    """One camera's entry of ``check.json``."""
    test = check.consistency
    entry: dict[str, Any] = {
        "moved": check.moved,
        "chi2": test.chi2,
        "dof": test.dof,
        "threshold": test.threshold,
        "p_value": test.p_value,
        "false_alarm_rate": test.false_alarm_rate,
        "stops": check.stops,
        "points": check.points,
        "station": station,
        "calibration": calibrated.path.name,
        "calibration_covariance": check.calibration_known,
    }
    new = check.repose
    if new is None:
        entry.update(
            shift_mm=None,
            turn_deg=None,
            shift_vector_mm=None,
            turn_vector_deg=None,
            repose_error=check.repose_error,
        )
    else:
        entry.update(
            shift_mm=float(1e3 * np.linalg.norm(new.shift_m)),
            turn_deg=float(np.degrees(np.linalg.norm(new.turn_rad))),
            shift_vector_mm=_mm(new.shift_m),
            turn_vector_deg=_deg(new.turn_rad),
            shift_std_mm=_mm(new.shift_std_m),
            turn_std_deg=_deg(new.turn_std_rad),
            repose_sigma_px=new.sigma_px,
        )
    moved = check.moved and new is not None
    entry["reposed"] = camera_to_dict(new.camera) if moved and new is not None else None
    entry["files"] = files
    if truth is not None:
        entry["truth"] = truth_entry(calibrated.camera, new.camera if new else None, truth)
    return entry


def truth_entry(
    calibrated: TsaiCamera, reposed: TsaiCamera | None, truth: TsaiCamera
) -> dict[str, Any]:
    """How the camera truly moved from its calibration, and the re-posed camera's error
    against the truth (the twin knows it)."""
    shift, turn = pose_change(calibrated, truth)
    out: dict[str, Any] = {
        "shift_vector_mm": _mm(shift),
        "turn_vector_deg": _deg(turn),
    }
    if reposed is not None:
        out["reposed_position_error_mm"] = float(
            1e3 * np.linalg.norm(reposed.position - truth.position)
        )
        out["reposed_rotation_error_deg"] = float(
            np.degrees(rotation_angle_between(reposed.world2cam_r, truth.world2cam_r))
        )
    return out


def check_results(
    outcome: CheckOutcome,
    calibrated: dict[str, CalibratedCamera],
    cameras_folder: Path,
    truth: dict[str, dict[str, Any]],
    meta: dict[str, Any],
    identity: Mapping[str, str] | None = None,
) -> dict[str, Any]:
    """``check.json``'s content; writes each moved camera's files into ``cameras_folder``
    (``NAME_check.json``, ``.yaml``, ``.camera_info.yaml``; the JSON file with the
    re-posed camera's covariance; the JSON and OpenCV files with ``identity``, the
    scenario checked in: :func:`twin.run.run_cameras.camera_identity`)."""
    cameras: dict[str, Any] = {}
    for name, check in outcome.checks.items():
        files: list[str] = []
        new = check.repose
        if check.moved and new is not None:
            for suffix in CAMERA_SUFFIXES:
                path = cameras_folder / f"{name}_check{suffix}"
                save_camera(new.camera, path, name, new.camera_covariance, identity)
                files.append(f"{cameras_folder.name}/{path.name}")
        true = truth.get(name)
        model = camera_from_dict(true, "truth") if true is not None else None
        cameras[name] = camera_entry(
            check,
            calibrated[name],
            outcome.station[name],
            model if isinstance(model, TsaiCamera) else None,
            files,
        )
    return {
        **meta,
        "cameras": cameras,
        "unchecked": dict(outcome.unchecked),
        "distance_travelled_m": outcome.travelled,
        "failures": dict(sorted(outcome.failures.items())),
        "events": dict(sorted(outcome.events.items())),
    }
