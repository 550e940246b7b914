"""The adjusted results of a run: its log's network adjusted as a whole
(:mod:`twin.localization.adjustment`), beside the sequential results.

:func:`adjusted_results` returns what ``results.json`` adds to
:func:`twin.campaign.log_results.results_from_log`'s content:

- ``adjusted_calibrations``: one entry per calibration, with the same fields as
  ``calibrations`` (the truth errors included); the parameters' standard deviations are
  the adjustment's, and the visit's LED points are mapped to W with the adjusted stations.
  With ``cameras="shared"`` (default) the visits of one camera are one camera, so their
  entries hold the same camera;
- ``adjusted_repeatability_mm``: second minus first adjusted calibration of each camera
  calibrated twice (zero by construction with ``cameras="shared"``);
- ``adjustment``: ``status`` (``adjusted``, ``nothing_to_add``, ``not_possible`` or
  ``failed``), a
  ``message``, what was measured twice (``redundancy``), the chi-square, its degrees of
  freedom and their ratio, the unknowns, the solver's evaluations and its wall time; where
  the children's marker assemblies are known only to their survey, ``marker_survey``: for
  each child, where its LEDs stand off the drawing in the frame its cubes (as drawn)
  define, and the standard deviations (mm): what a re-survey of that assembly's LEDs
  against its cubes would find.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from calib.io.camera_files import camera_from_dict
from calib.rotation import rot_z
from calib.tsai import TSAI_PARAMETERS, tsai_from_vector, tsai_reported
from twin.campaign.check.consistency import DEFAULT_FALSE_ALARM_RATE
from twin.campaign.log_results import (
    calibration_entry,
    reference_sets,
    visit_points,
)
from twin.campaign.network_log import LogNetworkError, network_from_log
from twin.campaign.records import CALIBRATION, DATASET, POINT
from twin.instruments.marker import MarkerAssembly
from twin.instruments.marker_pose import survey_covariance
from twin.localization.adjustment import AdjustedNetwork, NothingToAdjustError, adjust_network
from twin.truth import TRUTH_CAMERA

MIN_PIXEL_NOISE_PX = 1e-3
"""The pixel noise the adjustment weighs a noise-free camera's pixels with, px."""


def adjustment_settings(scenario: Any) -> dict[str, Any]:
    """What :func:`adjusted_results` needs of a scenario: each camera's pixel noise as the
    geometric and batch fidelities project it (at least :data:`MIN_PIXEL_NOISE_PX`), the
    children's creep, the surveyed control points, the pixel pitch and the marker
    assembly."""
    return {
        "marker": scenario.marker.assembly(),
        "pixel_noise_px": {
            c.name: max(scenario.projected_led_px(c.name), MIN_PIXEL_NOISE_PX)
            for c in scenario.cameras
        },
        "child_creep_m": scenario.campaign.child_creep_m,
        "control_points": {
            p.name: np.asarray(p.position, dtype=float)
            for p in getattr(scenario, "control_points", ())
            if p.surveyed
        },
        "pixel_size_mm": scenario.campaign.pixel_size_mm,
    }


def adjusted_results(
    messages: Iterable[Any],
    pixel_noise_px: float | Mapping[str, float] | None = None,
    *,
    cameras: str = "shared",
    child_creep_m: float = 0.0,
    control_points: Mapping[str, NDArray[np.float64]] | None = None,
    pixel_size_mm: float = 0.015,
    marker: MarkerAssembly | None = None,
) -> dict[str, Any]:
    """Adjust a run's log and return its adjusted results (see the module text).

    Args:
        messages: the log's messages in file order.
        pixel_noise_px, cameras, child_creep_m, control_points: as
            :func:`twin.campaign.network_log.network_from_log`.
        pixel_size_mm: the sensor's pixel pitch, for kappa1 in 1/mm^2.
        marker: the assembly as the campaign knew it (its drawing and survey), for the
            children's adjusted survey errors (``marker_survey``).
    """
    messages = list(messages)
    t0 = time.perf_counter()
    try:
        network, index = network_from_log(
            messages,
            pixel_noise_px,
            cameras=cameras,
            child_creep_m=child_creep_m,
            control_points=control_points,
        )
        adjusted = adjust_network(network)
    except NothingToAdjustError as exc:
        return _not_adjusted("nothing_to_add", str(exc), cameras)
    except LogNetworkError as exc:
        return _not_adjusted("not_possible", str(exc), cameras)
    except (ValueError, RuntimeError, np.linalg.LinAlgError) as exc:
        # A network the solver cannot solve (too few points for a camera, a singular
        # normal matrix): the sequential results stand; the run is not lost for it.
        return _not_adjusted(
            "failed", f"the adjustment failed: {type(exc).__name__}: {exc}", cameras
        )
    wall = time.perf_counter() - t0

    points = [m.data for m in messages if m.topic == POINT]
    sizes = {
        (d["dataset"], d["camera"], d["visit"]): d["points"]
        for d in (m.data for m in messages if m.topic == DATASET)
    }
    references = reference_sets(points, sizes)
    truths = {
        m.data["name"]: camera_from_dict(m.data["camera"], "truth")
        for m in messages
        if m.topic == TRUTH_CAMERA
    }
    records = [m.data for m in messages if m.topic == CALIBRATION]
    # The global test: a chi-square beyond what the stated noise allows means an error the
    # weights leave out (a marker surveyed worse than stated, say); the covariances are
    # then scaled by the a-posteriori variance factor, as a surveyor's adjustment does.
    consistent = adjusted.passes(DEFAULT_FALSE_ALARM_RATE)
    scale = 1.0 if consistent else adjusted.variance_factor
    entries = []
    first: dict[str, NDArray] = {}
    last: dict[str, NDArray] = {}
    for rec, stops in zip(records, index.calibration_stops, strict=True):
        c = index.camera_of(rec["camera"], int(rec["visit"]), cameras)
        size = tuple(int(v) for v in network.image_sizes[c])
        camera = tsai_from_vector(adjusted.cameras[c], size)
        _, cov = tsai_reported(adjusted.cameras[c], scale * adjusted.camera_covariances[c], size)
        std = dict(zip(TSAI_PARAMETERS, np.sqrt(np.maximum(np.diag(cov), 0.0)), strict=True))
        _, _, xy = visit_points(points, rec["camera"], int(rec["visit"]), int(rec["points"]))
        pts, pix = _adjusted_points(network, adjusted, stops)
        entries.append(
            calibration_entry(rec, camera, std, (pts, pix, xy), references, truths, pixel_size_mm)
        )
        first.setdefault(rec["camera"], camera.position)
        last[rec["camera"]] = camera.position
    return {
        "adjusted_calibrations": entries,
        "adjusted_repeatability_mm": {
            c: (1e3 * (last[c] - first[c])).tolist()
            for c in first
            if sum(e["camera"] == c for e in entries) > 1
        },
        "adjustment": {
            "status": "adjusted",
            "message": f"adjusted {len(network.stations)} stations and "
            f"{len(network.cameras)} cameras together"
            + (
                ""
                if consistent
                else f"; chi2/dof {adjusted.variance_factor:.2f} over {adjusted.dof} degrees "
                "of freedom fails the global test (false-alarm rate "
                f"{DEFAULT_FALSE_ALARM_RATE:g}): the measurements disagree more than their "
                "stated noise allows, and the adjusted standard deviations are scaled by it"
            ),
            "cameras": cameras,
            "redundancy": list(adjusted.redundancy),
            "chi2": adjusted.chi2,
            "dof": adjusted.dof,
            "variance_factor": adjusted.variance_factor,
            "consistent": consistent,
            "covariance_scale": scale,
            "unknowns": int(
                4 * (len(network.stations) - 1)
                + 3 * int((~network.known_targets).sum())
                + 11 * len(network.cameras)
                + sum(len(z) for z in adjusted.surveys.values())
            ),
            "evaluations": adjusted.evaluations,
            "wall_time_s": wall,
            **_marker_survey(network, adjusted, marker, scale),
        },
    }


SURVEY_MATCH = 1e-6
"""Relative difference between the logged survey loadings' size and the assembly's above
which the log was not recorded with that assembly's survey."""


def _marker_survey(
    network: Any, adjusted: AdjustedNetwork, marker: MarkerAssembly | None, scale: float
) -> dict[str, Any]:
    """``marker_survey``: each child's LEDs' offset from the drawing in the frame its cubes
    define, ``C z`` (C the survey's factor, z its adjusted error), and its standard
    deviations, mm; nothing where no survey error was adjusted, and a message where the
    assembly given is not the one the log's loadings were made with (a stop's loading is
    C turned, so both have the same size)."""
    if not adjusted.surveys or marker is None:
        return {}
    factor = np.linalg.cholesky(survey_covariance(marker)) if marker.survey_sigma else None
    # A stop that showed every LED: its loading has the size of C.
    whole = [s.survey_level for s in network.led_sightings if s.survey_level.size]
    whole = [load for load in whole if factor is not None and load.shape == factor.shape]
    if factor is None or (
        whole
        and not np.isclose(np.linalg.norm(whole[0]), np.linalg.norm(factor), rtol=SURVEY_MATCH)
    ):
        message = (
            "the log's stops were recorded with another marker survey than the scenario's "
            "marker.survey_sigma_m: the LEDs' offsets are not reported"
        )
        return {"marker_survey": {"message": message}}
    out: dict[str, Any] = {}
    for child, z in sorted(adjusted.surveys.items()):
        cov = scale * factor @ adjusted.survey_covariances[child] @ factor.T
        out[child] = {
            "leds_offset_mm": (1e3 * (factor @ z)).reshape(-1, 3).tolist(),
            "leds_offset_std_mm": (1e3 * np.sqrt(np.maximum(np.diag(cov), 0.0)))
            .reshape(-1, 3)
            .tolist(),
        }
    return {"marker_survey": out}


def _adjusted_points(
    network: Any, adjusted: AdjustedNetwork, stops: tuple[int, ...]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A calibration's LED points mapped to W with the adjusted stations, and its pixels."""
    pts, pix = [], []
    for i in stops:
        s = network.led_sightings[i]
        pose = adjusted.stations[s.station]
        level = s.leds_level
        if s.survey_level.size:  # where the child's adjusted survey puts its LEDs
            level = level + (s.survey_level @ adjusted.surveys[s.child]).reshape(-1, 3)
        pts.append(level @ rot_z(pose[0]).T + pose[1:])
        pix.append(s.pixels)
    if not pts:
        return np.zeros((0, 3)), np.zeros((0, 2))
    return np.vstack(pts), np.vstack(pix)


def _not_adjusted(status: str, message: str, cameras: str) -> dict[str, Any]:
    return {
        "adjusted_calibrations": [],
        "adjusted_repeatability_mm": {},
        "adjustment": {"status": status, "message": message, "cameras": cameras},
    }
