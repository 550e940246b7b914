"""Run the campaign on a rig, log every reading, and write what the run gives: the part of
a run that does not depend on the backend (the twin's :mod:`twin.run.runner`, real devices'
:mod:`twin.run.hardware_run`).

- ``DIR/log.mcap`` (every reading, as it arrives), ``DIR/results.json``, ``DIR/cameras/``
  (JSON with the camera's covariance, OpenCV YAML, ROS camera_info per calibration),
  ``DIR/figures/`` and ``DIR/report.md``.

A campaign that was aborted (a device lost, CPS unable to go on) leaves the scenario's
visits it never made in the log as skipped, with the abort's reason
(:func:`skip_visits_not_made`).
"""

from __future__ import annotations

import datetime
import json
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from calib.io.camera_files import camera_from_dict, save_camera
from twin.campaign import Campaign, CampaignOutcome, Progress
from twin.campaign.adjusted_results import adjusted_results, adjustment_settings
from twin.campaign.journal import Journal
from twin.campaign.log_results import META, SUMMARY, results_from_log
from twin.campaign.records import FAILURE
from twin.campaign.strategy import Strategy
from twin.hal.recording import Recorder, recorded
from twin.hal.rig import Rig
from twin.outputs import claim_folder, write_text_atomic
from twin.record import McapRecorder, read_log
from twin.record.foxglove import FoxgloveStream
from twin.record.run_record import scenario_fields
from twin.report import write_report
from twin.report.reading import planned_visits
from twin.run.run_cameras import camera_identity
from twin.scenario import Scenario

if TYPE_CHECKING:
    from twin.record.foxglove.live import LiveServer

RigOpener = Callable[[McapRecorder], tuple[Rig, Callable[[], None], dict[str, float]]]
"""Given the run's log, opens the devices; returns them, what closes them, and the
backend's timings by activity (filled as it runs)."""


def run_campaign(
    sc: Scenario,
    out_dir: str | Path,
    arguments: dict[str, Any],
    meta: dict[str, Any],
    open_rig: RigOpener,
    strategy: Strategy,
    progress: Callable[[Progress], None] | None,
    report: bool,
    overwrite: bool,
    cameras: bool = True,
    *,
    foxglove: bool = True,
    live: LiveServer | None = None,
) -> dict[str, Any]:
    """Run the campaign on the rig ``open_rig`` gives, log it, and write its outputs.

    Args:
        sc: the scenario. out_dir: the run's folder (see :func:`run_scenario`).
        arguments: what the folder is claimed for (:func:`twin.outputs.claim_folder`).
        meta: the run's description beside the scenario and strategy (``fidelity``,
            ``seed``...), the log's first record.
        open_rig: given the log, opens the devices and returns them, what closes them, and
            the backend's timings (filled as it runs). The devices are closed (robots
            stopped) however the campaign ends, Ctrl-C included; the log keeps what came.
        strategy: the campaign's strategy. progress, report, overwrite, cameras,
            foxglove, live: as :func:`twin.run.runner.run_scenario`.
    """
    folder = claim_folder(Path(out_dir), "run", RUN_OUTPUTS, arguments, overwrite=overwrite)
    with folder:  # held until the run ends, however it ends
        out = folder.path
        log_path = out / "log.mcap"
        t0 = time.perf_counter()
        stream = FoxgloveStream(sc) if foxglove else None
        if live is not None and stream is not None:
            stream = live.tee(stream)
        with McapRecorder(log_path, foxglove=stream) as log:
            log.record(
                META,
                {
                    **scenario_fields(sc),
                    **camera_identity(sc),
                    **meta,
                    "strategy": strategy.name,
                    "started": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
                },
                0.0,
            )
            devices, close, backend_timings = open_rig(log)
            try:
                rig = recorded(devices, log)
                watch = AbortWatch(log)
                campaign = Campaign(rig, sc, watch, progress, strategy)
                outcome = campaign.run()
                if watch.aborted is not None:
                    skip_visits_not_made(campaign.journal, outcome, sc, watch.aborted)
                wall = time.perf_counter() - t0
                timings = dict(backend_timings)
                if "observe" in timings:
                    observe = timings.pop("observe")
                    timings["detection"] = max(observe - timings.get("render", 0.0), 0.0)
                timings["other"] = max(wall - sum(timings.values()), 0.0)
                log.record(
                    SUMMARY,
                    {"wall_time_s": wall, "timings_s": timings},
                    rig.clock.now(),
                )
            finally:
                close()
        messages = read_log(log_path).messages
        results = results_from_log(messages, sc.campaign.pixel_size_mm)
        results.update(adjusted_results(messages, **adjustment_settings(sc)))
        text = json.dumps(results, indent=2, allow_nan=False) + "\n"
        write_text_atomic(out / "results.json", text)
        if cameras:
            write_cameras(results, messages, out / "cameras", camera_identity(sc))
        if report:
            write_report(sc, results, out)
        folder.finished(calibrations=len(results["calibrations"]))
    return results


class AbortWatch:
    """A recorder that hands every record on to ``inner`` and keeps the message of the
    campaign's abort (its last ``campaign_aborted`` failure; None while it has none)."""

    def __init__(self, inner: Recorder) -> None:
        self.inner = inner
        self.aborted: str | None = None

    def record(self, topic: str, record: object, timestamp: float) -> None:
        if topic == FAILURE and getattr(record, "kind", None) == "campaign_aborted":
            self.aborted = str(getattr(record, "message", ""))
        self.inner.record(topic, record, timestamp)


def skip_visits_not_made(
    journal: Journal, outcome: CampaignOutcome, sc: Scenario, aborted: str
) -> list[tuple[str, int]]:
    """Record as skipped (``campaign_aborted``, the message naming the abort) each of the
    scenario's visits that an aborted campaign neither calibrated nor skipped; returns
    them, (camera, visit number), in the scenario's order."""
    made = {(c.camera, c.visit) for c in outcome.calibrations}
    made |= {(s.camera, s.visit) for s in outcome.skipped}
    missed = []
    for key, station in planned_visits(sc):
        if key not in made:
            message = f"the campaign was aborted: {aborted}"
            journal.skipped(key[0], key[1], np.asarray(station), "campaign_aborted", message)
            missed.append(key)
    return missed


def dropped_visits(results: Mapping[str, Any], sc: Scenario) -> list[dict[str, Any]]:
    """The scenario's visits that a run's ``results`` hold no calibration of, in the
    scenario's order: each ``camera``, ``visit`` (its number among the camera's visits),
    ``station`` ((2,) W, m), and the ``reason`` and ``message`` its skipped visit recorded
    (``not_made`` and no message for a visit the log does not mention)."""
    made = {(str(c["camera"]), int(c["visit"])) for c in results["calibrations"]}
    skipped = {(str(s["camera"]), int(s["visit"])): s for s in results["skipped_visits"]}
    out = []
    for key, station in planned_visits(sc):
        if key in made:
            continue
        entry = skipped.get(key, {})
        out.append(
            {
                "camera": key[0],
                "visit": key[1],
                "station": list(station),
                "reason": str(entry.get("reason", "not_made")),
                "message": str(entry.get("message") or ""),
            }
        )
    return out


RUN_OUTPUTS = ("log.mcap", "results.json", "cameras", "figures", "report.md")
"""What a run writes in its folder (and clears there with ``overwrite``)."""


def write_cameras(
    results: dict[str, Any],
    messages: Any,
    folder: Path,
    identity: Mapping[str, str] | None = None,
) -> list[Path]:
    """Each calibrated camera as ``NAME_visitK.json``, ``.yaml`` (OpenCV) and
    ``.camera_info.yaml`` (ROS) in ``folder``, the JSON and OpenCV files with ``identity``,
    the scenario the run was made in (:func:`twin.run.run_cameras.camera_identity`).

    A Tsai camera's JSON file also holds its covariance in W (``covariance``: see
    :mod:`calib.camera_covariance`), propagated from its visit's data as the log holds
    them (:func:`twin.run.logged_points.calibration_covariances`): what ``twin check`` weighs
    the calibration's own error by.
    """
    from twin.campaign.records import CALIBRATION
    from twin.run.logged_points import calibration_covariances

    messages = list(messages)
    covariances = calibration_covariances(messages)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for m in messages:
        if m.topic != CALIBRATION:
            continue
        camera = camera_from_dict(m.data["camera_model"], "calibration")
        stem = f"{m.data['camera']}_visit{m.data['visit']}"
        cov = covariances.get((m.data["camera"], int(m.data["visit"])))
        for suffix in (".json", ".yaml", ".camera_info.yaml"):
            path = folder / f"{stem}{suffix}"
            save_camera(camera, path, m.data["camera"], cov, identity)
            written.append(path)
    return written
