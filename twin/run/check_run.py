"""Check a run's calibrated cameras on a rig, log every reading, and write what the check
gives: the part of ``twin check`` that does not depend on the backend (the twin's
:func:`twin.run.runner.check_scenario`, real devices' :func:`twin.run.hardware_run.check_on_rig`).

- ``OUT/log.mcap``: every reading and the campaign's records, as they arrive;
- ``OUT/check.json`` (:mod:`twin.run.check_results`) and ``OUT/cameras/`` (the moved
  cameras, re-posed).
"""

from __future__ import annotations

import datetime
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from twin.campaign import Progress
from twin.campaign.check import (
    MIN_PIXEL_SIGMA,
    check_cameras,
    check_min_pixel_sigma,
    check_stops,
)
from twin.campaign.check.consistency import check_false_alarm_rate
from twin.campaign.log_results import META
from twin.campaign.strategy import Strategy
from twin.hal.recording import Recorder
from twin.hal.rig import Rig
from twin.outputs import claim_folder, write_text_atomic
from twin.record import McapRecorder
from twin.record.foxglove import FoxgloveStream
from twin.run.check_results import check_results
from twin.run.run_cameras import camera_identity, latest_cameras
from twin.scenario import Scenario
from twin.truth import TRUTH_CAMERA

CHECK_OUTPUTS = ("log.mcap", "check.json", "cameras")
"""What a check writes in its folder (and clears there with ``overwrite``)."""

CheckOpener = Callable[[Recorder], tuple[Rig, Callable[[], None]]]
"""Given where the records go, opens the devices (the parent at its first station);
returns them and what closes them."""


class _TruthTap:
    """A recorder that passes every record on and keeps the cameras' truth (the twin's, or
    an emulator's) by name."""

    def __init__(self, inner: Recorder) -> None:
        self.inner = inner
        self.cameras: dict[str, dict[str, Any]] = {}

    def record(self, topic: str, record: object, timestamp: float) -> None:
        self.inner.record(topic, record, timestamp)
        if topic == TRUTH_CAMERA and isinstance(record, dict):
            self.cameras[str(record["name"])] = dict(record["camera"])


def run_check(
    sc: Scenario,
    cameras_dir: str | Path,
    out_dir: str | Path,
    arguments: dict[str, Any],
    meta: dict[str, Any],
    open_rig: CheckOpener,
    strategy: Strategy,
    *,
    stops: int,
    false_alarm_rate: float,
    min_pixel_sigma: float = MIN_PIXEL_SIGMA,
    progress: Callable[[Progress], None] | None = None,
    overwrite: bool = False,
) -> dict[str, Any]:
    """Check the latest calibration of each camera in ``cameras_dir`` on the rig
    ``open_rig`` gives, log it, and write ``check.json`` and the moved cameras' files.

    Args:
        sc: the scenario. cameras_dir: the ``cameras/`` folder a run wrote.
        out_dir: the check's folder (new or empty, unless ``overwrite``).
        arguments: what the folder is claimed for (:func:`twin.outputs.claim_folder`).
        meta: the check's description (``fidelity``, ``seed``...), the log's first record
            and ``check.json``'s first keys.
        open_rig: opens the devices; they are closed however the check ends.
        strategy: the campaign's strategy (its legs and data stops).
        stops, false_alarm_rate, min_pixel_sigma: as
            :func:`twin.campaign.check.check_cameras`.
        progress: called with each :class:`Progress`. overwrite: as ``twin run``'s.

    Returns:
        ``check.json``'s content.

    Raises:
        twin.run.run_cameras.CamerasFolderError: the cameras folder cannot be checked.
        ValueError: bad stops, false-alarm rate or least pixel sigma.
        twin.outputs.OutputError: ``out_dir`` cannot be used. Nothing is written for any
            of these.
    """
    calibrated = latest_cameras(cameras_dir, sc)
    stops = check_stops(stops)
    alpha = check_false_alarm_rate(false_alarm_rate)
    sigma = check_min_pixel_sigma(min_pixel_sigma)
    folder = claim_folder(Path(out_dir), "check", CHECK_OUTPUTS, arguments, overwrite=overwrite)
    out = folder.path
    identity = camera_identity(sc)
    header = {
        **identity,
        "scenario_file": sc.source,
        "cameras_dir": str(cameras_dir),
        **meta,
        "strategy": strategy.name,
        "stops": stops,
        "false_alarm_rate": alpha,
        "min_pixel_sigma_px": sigma,
    }
    started = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
    with McapRecorder(out / "log.mcap", foxglove=FoxgloveStream(sc)) as log:
        log.record(META, {**header, "command": "check", "started": started}, 0.0)
        tap = _TruthTap(log)
        devices, close = open_rig(tap)
        try:
            outcome = check_cameras(
                devices,
                sc,
                {name: c.camera for name, c in calibrated.items()},
                tap,
                covariances={
                    name: c.covariance for name, c in calibrated.items() if c.covariance is not None
                },
                stops=stops,
                false_alarm_rate=alpha,
                min_pixel_sigma=sigma,
                strategy=strategy,
                progress=progress,
            )
        finally:
            close()
    results = check_results(outcome, calibrated, out / "cameras", tap.cameras, header, identity)
    write_text_atomic(out / "check.json", json.dumps(results, indent=2, allow_nan=False) + "\n")
    folder.finished(
        checked=len(outcome.checks),
        moved=sum(c.moved for c in outcome.checks.values()),
    )
    return results
