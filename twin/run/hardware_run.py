"""Run the calibration campaign of a scenario on real devices (or on emulated ones), or
check a run's calibrated cameras on them (:func:`check_on_rig`).

The devices come from a rig file (:mod:`twin.drivers.rig_file`); the scenario still gives
the map, the cameras' nominal poses, the route, the visits and the instrument's noise. The
run is logged and written as a twin run is (:mod:`twin.run.campaign_run`). A run against
``twin emulate`` also records the emulated world's cameras as the truth, so its results
carry errors against the truth as a twin run's do.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from twin.campaign import Progress
from twin.campaign.check import DEFAULT_FALSE_ALARM_RATE, DEFAULT_STOPS, MIN_PIXEL_SIGMA
from twin.campaign.strategies import strategy_for
from twin.campaign.strategy import Strategy
from twin.drivers.build import build_rig, check_drivers
from twin.drivers.rig_file import RigFile, RigFileError, check_fits, load_rig_file
from twin.hal.recording import Recorder
from twin.hal.rig import Rig
from twin.record import McapRecorder
from twin.run.campaign_run import run_campaign
from twin.run.check_run import run_check
from twin.scenario import Scenario, load_scenario
from twin.scenario.errors import ScenarioIssue
from twin.truth import TRUTH_CAMERA

if TYPE_CHECKING:
    from twin.record.foxglove.live import LiveServer

DEVICE = "/rig/device"
"""Topic of what each device said about itself when it was opened (name, serial number,
battery, resolution...), one record per device at the start of a run."""


def run_on_rig(
    scenario: Scenario | str | Path,
    rig_file: RigFile | str | Path,
    out_dir: str | Path,
    *,
    progress: Callable[[Progress], None] | None = None,
    report: bool = True,
    strategy: Strategy | str | None = None,
    overwrite: bool = False,
    live: LiveServer | None = None,
) -> dict[str, Any]:
    """Run the campaign of ``scenario`` on the devices of ``rig_file``.

    Args:
        scenario: a scenario or its file. rig_file: a rig file or its path.
        out_dir, progress, report, strategy, overwrite, live: as
            :func:`twin.run.runner.run_scenario`.

    Returns:
        The results (also in ``results.json``).

    Raises:
        twin.drivers.rig_file.RigFileError: the rig file is bad or lacks a device the
            scenario needs; ImportError: a driver's optional package is missing;
            twin.outputs.OutputError: ``out_dir`` cannot be used (nothing is written for
            any of these).
        twin.drivers.build.DeviceConnectError: a device could not be opened (the log so far
            is kept).
    """
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    rig = _fitting_rig(rig_file, sc)
    chosen = strategy_for(sc, strategy)
    truth = emulated_truth(rig)
    arguments = {
        "scenario": sc.source or sc.name,
        "rig": rig.source or rig.name,
        "strategy": chosen.name,
    }

    def open_rig(log: McapRecorder) -> tuple[Rig, Callable[[], None], dict[str, float]]:
        devices, close = _open_devices(rig, sc, truth, log)
        return devices, close, devices.timings

    meta = {"fidelity": "hardware", "rig": rig.source or rig.name, "seed": sc.seed}
    return run_campaign(
        sc, out_dir, arguments, meta, open_rig, chosen, progress, report, overwrite, live=live
    )


def check_on_rig(
    scenario: Scenario | str | Path,
    rig_file: RigFile | str | Path,
    cameras_dir: str | Path,
    out_dir: str | Path,
    *,
    stops: int = DEFAULT_STOPS,
    false_alarm_rate: float = DEFAULT_FALSE_ALARM_RATE,
    min_pixel_sigma: float = MIN_PIXEL_SIGMA,
    progress: Callable[[Progress], None] | None = None,
    strategy: Strategy | str | None = None,
    overwrite: bool = False,
) -> dict[str, Any]:
    """Check on the devices of ``rig_file`` whether the cameras a run calibrated
    (``cameras_dir``) are still where their calibrations say (:func:`twin.run.check_run.
    run_check`). The parent must stand where it stood at the calibration's first station,
    heading as it did: that station defines W.

    Args:
        scenario, rig_file: as :func:`run_on_rig`. cameras_dir, out_dir, stops,
            false_alarm_rate, min_pixel_sigma, progress, strategy, overwrite: as
            :func:`twin.run.runner.check_scenario`.

    Raises:
        twin.drivers.rig_file.RigFileError: the rig file is bad or lacks a device the
            scenario needs; ImportError: a driver's optional package is missing;
            twin.run.run_cameras.CamerasFolderError, ValueError,
            twin.outputs.OutputError: as :func:`twin.run.check_run.run_check` (nothing is
            written). twin.drivers.build.DeviceConnectError: a device could not be opened
            (the log so far is kept).
    """
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    rig = _fitting_rig(rig_file, sc)
    chosen = strategy_for(sc, strategy)
    truth = emulated_truth(rig)
    arguments = {
        "scenario": sc.source or sc.name,
        "cameras": str(cameras_dir),
        "rig": rig.source or rig.name,
        "stops": stops,
        "false_alarm_rate": false_alarm_rate,
        "min_pixel_sigma": min_pixel_sigma,
        "strategy": chosen.name,
    }

    def open_rig(log: Recorder) -> tuple[Rig, Callable[[], None]]:
        return _open_devices(rig, sc, truth, log)

    meta = {"fidelity": "hardware", "rig": rig.source or rig.name}
    return run_check(
        sc,
        cameras_dir,
        out_dir,
        arguments,
        meta,
        open_rig,
        chosen,
        stops=stops,
        false_alarm_rate=false_alarm_rate,
        min_pixel_sigma=min_pixel_sigma,
        progress=progress,
        overwrite=overwrite,
    )


def _fitting_rig(rig_file: RigFile | str | Path, sc: Scenario) -> RigFile:
    """The rig file, read and checked against the scenario (a device for every robot and
    camera, a bit for every LED) and its drivers loadable, before anything is written or
    opened.

    Raises:
        RigFileError: naming the file and each problem. ImportError: a driver's optional
            package is missing.
    """
    rig = rig_file if isinstance(rig_file, RigFile) else load_rig_file(rig_file)
    check_fits(rig, sc)
    check_drivers(rig)
    return rig


def _open_devices(
    rig: RigFile, sc: Scenario, truth: dict[str, dict[str, Any]], log: Recorder
) -> tuple[Rig, Callable[[], None]]:
    """The rig file's devices, opened; what each said about itself and the emulated
    truth recorded first. Returns the devices and what closes them."""
    devices = build_rig(rig, sc)
    try:
        for name, identity in devices.identities.items():
            log.record(DEVICE, {"device": name, **_plain(identity)}, 0.0)
        for name, camera in truth.items():
            log.record(TRUTH_CAMERA, {"name": name, "camera": camera}, 0.0)
    except BaseException:
        devices.close()
        raise
    return devices.rig, devices.close


def emulated_truth(rig: RigFile) -> dict[str, dict[str, Any]]:
    """The cameras' true models in W that ``twin emulate`` wrote beside its rig file, by
    name; empty for real hardware.

    Raises:
        RigFileError: the truth file named by the rig file cannot be read.
    """
    if rig.emulator is None:
        return {}
    path = Path(rig.emulator.truth)
    if not path.is_absolute() and rig.source is not None:
        path = Path(rig.source).parent / path
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        return {str(k): dict(v) for k, v in data["cameras"].items()}
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        issue = ScenarioIssue("emulator.truth", str(exc), str(path), "the truth file it wrote")
        raise RigFileError(rig.source or "<rig>", [issue]) from None


def _plain(values: dict[str, Any]) -> dict[str, Any]:
    """``values`` as a log holds them: numbers, strings, bools and lists of them; anything
    else as its text."""

    def plain(v: Any) -> Any:
        if v is None or isinstance(v, bool | int | float | str):
            return v
        if isinstance(v, list | tuple):
            return [plain(x) for x in v]
        return str(v)

    return {str(k): plain(v) for k, v in values.items()}
