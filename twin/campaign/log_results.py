"""A campaign's results, computed from what its log recorded.

:func:`results_from_log` reads the records of a run (``/campaign/...``, and ``/truth/...``
when a simulation wrote its truth beside them, :mod:`twin.truth`) and returns the content of
``results.json``: every calibration with its parameters in the paper's units, the Table III
errors (world: against the reference data sets measured from the first station; local:
against the data taken at that station), the errors against the truth, the repeatability of
cameras calibrated twice, the parent's track, and every failure and event by kind.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from calib.camera import TsaiCamera
from calib.io.camera_files import camera_from_dict
from calib.metrics import evaluate
from calib.paper_units import kappa1_px2mm
from twin.campaign.records import (
    CALIBRATION,
    DATASET,
    EVENT,
    FAILURE,
    PARENT_FIX,
    POINT,
    SKIPPED,
)
from twin.truth import TRUTH_CAMERA, TRUTH_INSTRUMENT, instrument_truth

META = "/run/meta"
"""Topic of the run's description (scenario, fidelity, seed), written first."""
SUMMARY = "/run/summary"
"""Topic of the run's wall time and timings, written last."""


def _array(values: Any) -> NDArray[np.float64]:
    return np.array([np.nan if v is None else v for v in np.ravel(values)], dtype=float).reshape(
        np.shape(values)
    )


def _by_topic(messages: Iterable[Any]) -> dict[str, list[dict[str, Any]]]:
    out: dict[str, list[dict[str, Any]]] = {}
    for m in messages:
        out.setdefault(m.topic, []).append(m.data)
    return out


def point_arrays(points: list[Mapping[str, Any]]) -> tuple[NDArray, NDArray, NDArray]:
    """(N, 3) LED points, (N, 2) pixels and (K, 2) child positions of data points."""
    if not points:
        return np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 2))
    pts = np.vstack([_array(p["leds_world"]) for p in points])
    pix = np.vstack([_array(p["pixels"]) for p in points])
    xy = np.array([_array(p["child_xy"]) for p in points])
    return pts, pix, xy


def _errors(camera: Any, pts: NDArray, pix: NDArray) -> dict[str, float] | None:
    if len(pts) == 0:
        return None
    m = evaluate(camera, pts, pix)
    return {
        "pixel_mean": m.pixel.mean,
        "pixel_rms": m.pixel.rms,
        "error_3d_mean_mm": 1e3 * m.error_3d.mean,
        "error_3d_rms_mm": 1e3 * m.error_3d.rms,
        "points": m.n_points,
    }


def _truth(camera: Any, truth: Any) -> dict[str, Any]:
    r = camera.world2cam_r @ truth.world2cam_r.T
    angle = float(np.degrees(Rotation.from_matrix(r).magnitude()))
    return {
        "position_error_mm": float(1e3 * np.linalg.norm(camera.position - truth.position)),
        "position_mm": (1e3 * truth.position).tolist(),
        "rotation_error_deg": angle,
    }


def _parameters(camera: Any, pixel_size_mm: float) -> dict[str, Any]:
    out: dict[str, Any] = {"position_mm": (1e3 * camera.position).tolist()}
    if isinstance(camera, TsaiCamera):
        out.update(
            f_px=camera.f,
            cx=camera.cx,
            cy=camera.cy,
            sx=camera.sx,
            kappa1_px=camera.kappa1,
            kappa1_per_mm2=kappa1_px2mm(camera.kappa1, pixel_size_mm),
            rotation_deg=np.degrees(camera.rotation_rad).tolist(),
        )
    return out


def visit_points(
    points: list[Mapping[str, Any]], camera: str, visit: int, n: int
) -> tuple[NDArray, NDArray, NDArray]:
    """The first ``n`` LED points of a visit's data points (the calibration's data set):
    (n, 3) points, (n, 2) pixels and (K, 2) child positions."""
    mine = [
        p
        for p in points
        if p["dataset"] == "visit" and p["camera"] == camera and p["visit"] == visit
    ]
    pts, pix, xy = point_arrays(mine)
    return pts[:n], pix[:n], xy


def calibration_entry(
    rec: Mapping[str, Any],
    camera: Any,
    std: Mapping[str, float],
    data: tuple[NDArray, NDArray, NDArray],
    references: Mapping[str, tuple[NDArray, NDArray]],
    truths: Mapping[str, Any],
    pixel_size_mm: float,
) -> dict[str, Any]:
    """One calibration as ``results.json`` lists it.

    Args:
        rec: the calibration's record (``CalibrationRecord`` fields). camera: the camera.
        std: its parameters' standard deviations by name (SI).
        data: the visit's (N, 3) LED points, (N, 2) pixels and (K, 2) child positions.
        references: each camera's reference data set (points, pixels).
        truths: the true cameras by name (a simulation's). pixel_size_mm: for kappa1.
    """
    cam_name = rec["camera"]
    pts, pix, xy = data
    ref = references.get(cam_name)
    return {
        "camera": cam_name,
        "visit": rec["visit"],
        "station": _array(rec["station"]).tolist(),
        "distance_travelled_m": rec["distance_travelled"],
        "points": rec["points"],
        "sigma_px": rec["sigma_px"],
        "parameters": _parameters(camera, pixel_size_mm),
        "std": dict(std),
        "errors": {
            "world": _errors(camera, *ref) if ref is not None else None,
            "local": _errors(camera, pts, pix),
        },
        "truth": _truth(camera, truths[cam_name]) if cam_name in truths else None,
        "residuals_px": (pix - camera.project(pts)).tolist() if len(pts) else [],
        "data_points_xy": xy.tolist(),
    }


def reference_sets(
    points: list[Mapping[str, Any]], sizes: Mapping[tuple[str, str, int], int]
) -> dict[str, tuple[NDArray, NDArray]]:
    """Each camera's reference data set: (N, 3) points and (N, 2) pixels."""
    references: dict[str, tuple[NDArray, NDArray]] = {}
    for cam in dict.fromkeys(p["camera"] for p in points if p["dataset"] == "reference"):
        pts, pix, _ = point_arrays(
            [p for p in points if p["dataset"] == "reference" and p["camera"] == cam]
        )
        n = sizes.get(("reference", cam, 0), len(pts))
        references[cam] = (pts[:n], pix[:n])
    return references


def results_from_log(messages: Iterable[Any], pixel_size_mm: float = 0.015) -> dict[str, Any]:
    """The results of a run from its log's messages (``LogContents.messages``).

    Args:
        messages: the log's messages, each with ``topic`` and ``data`` (the record's fields).
        pixel_size_mm: the sensor's pixel pitch, for kappa1 in 1/mm^2.

    Returns:
        The content of ``results.json`` (see docs/reports.md); a log cut short gives the results
        of what it holds, with ``complete`` False.
    """
    t = _by_topic(messages)
    meta = (t.get(META) or [{}])[0]
    summary = (t.get(SUMMARY) or [None])[-1]
    points = t.get(POINT, [])
    sizes = {(d["dataset"], d["camera"], d["visit"]): d["points"] for d in t.get(DATASET, [])}
    references = reference_sets(points, sizes)
    truths = {d["name"]: camera_from_dict(d["camera"], "truth") for d in t.get(TRUTH_CAMERA, [])}

    calibrations = []
    first_position: dict[str, NDArray] = {}
    last_position: dict[str, NDArray] = {}
    for rec in t.get(CALIBRATION, []):
        cam_name, visit = rec["camera"], rec["visit"]
        camera = camera_from_dict(rec["camera_model"], f"calibration of {cam_name}")
        pts, pix, xy = visit_points(points, cam_name, visit, rec["points"])
        entry = calibration_entry(
            rec, camera, rec["std"], (pts, pix, xy), references, truths, pixel_size_mm
        )
        calibrations.append(entry)
        first_position.setdefault(cam_name, camera.position)
        last_position[cam_name] = camera.position

    fixes = t.get(PARENT_FIX, [])
    true_at_fix = instrument_truth(t.get(TRUTH_INSTRUMENT, []), [f["timestamp"] for f in fixes])
    estimated = [_array(f["translation"])[:2].tolist() for f in fixes]
    true_track = [true[:2].tolist() for true in true_at_fix if true is not None]
    final_error = None
    if fixes and true_at_fix[-1] is not None:
        est = _array(fixes[-1]["translation"])
        final_error = float(1e3 * np.linalg.norm(est - true_at_fix[-1]))
    failures = Counter(f["kind"] for f in t.get(FAILURE, []))
    aborts = [f["message"] for f in t.get(FAILURE, []) if f["kind"] == "campaign_aborted"]
    for s in t.get(SKIPPED, []):
        failures[f"visit_{s['reason']}"] += 1
    return {
        "scenario": meta.get("scenario", ""),
        "scenario_file": meta.get("scenario_file", ""),
        "fidelity": meta.get("fidelity", ""),
        "strategy": meta.get("strategy", ""),
        "seed": meta.get("seed"),
        "complete": summary is not None,
        "wall_time_s": None if summary is None else summary["wall_time_s"],
        "timings_s": None if summary is None else summary["timings_s"],
        "pixel_size_mm": pixel_size_mm,
        "reference_sets": [{"camera": c, "points": len(p)} for c, (p, _) in references.items()],
        "calibrations": calibrations,
        "skipped_visits": [
            {
                "camera": s["camera"],
                "visit": s["visit"],
                "station": _array(s["station"]).tolist(),
                "reason": s["reason"],
                "message": s["message"],
            }
            for s in t.get(SKIPPED, [])
        ],
        "repeatability_mm": {
            c: (1e3 * (last_position[c] - first_position[c])).tolist()
            for c in first_position
            if sum(e["camera"] == c for e in calibrations) > 1
        },
        "parent_final_error_mm": final_error,
        "distance_travelled_m": fixes[-1]["distance_travelled"] if fixes else 0.0,
        "parent_track": {"estimated": estimated, "true": true_track},
        "failures": dict(sorted(failures.items())),
        "aborted": aborts[-1] if aborts else None,
        "events": dict(sorted(Counter(e["kind"] for e in t.get(EVENT, [])).items())),
    }
