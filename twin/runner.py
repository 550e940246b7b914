"""Run the calibration campaign of a scenario in the twin, and write everything it gives.

This is the one place where the backend is chosen: a simulated rig at the ``render`` or
``geometric`` fidelity (:mod:`twin.sim.rig`) is built on the scenario's world, wrapped so
that every reading goes to ``DIR/log.mcap`` as it arrives, and handed to
:class:`twin.campaign.Campaign` with its strategy. The simulation records its own truth
(camera poses, the instrument's true pose at every CPS fix) beside the readings, under
``/truth/`` (:mod:`twin.truth`). The results are then computed from the log alone
(:func:`twin.campaign.log_results.results_from_log`):

- ``DIR/results.json``, ``DIR/cameras/`` (JSON, OpenCV YAML, ROS camera_info per
  calibration), ``DIR/figures/`` and ``DIR/report.md``.
"""

from __future__ import annotations

import datetime
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

import twin.sim  # noqa: F401  (headless rendering is configured before MuJoCo loads)
from calib.io.camera_files import camera_from_dict, save_camera
from twin.campaign import Campaign, Progress
from twin.campaign.log_results import META, SUMMARY, results_from_log
from twin.campaign.strategies import strategy_for
from twin.hal.recording import recorded
from twin.hal.rig import Rig
from twin.instruments.marker import MarkerAssembly
from twin.outputs import claim_folder, write_text_atomic
from twin.record import McapRecorder, read_log
from twin.report import write_report
from twin.scenario import Scenario, load_scenario
from twin.scenario.limits import check_seed
from twin.scenario.schema import Noise
from twin.sim.rig import FIDELITIES, SimRig, build_sim_rig
from twin.sim.world import build_world


def run_scenario(
    scenario: Scenario | str | Path,
    out_dir: str | Path,
    *,
    fidelity: str = "render",
    seed: int | None = None,
    noise: bool = True,
    progress: Callable[[Progress], None] | None = None,
    report: bool = True,
    advertised_noise: Noise | None = None,
    strategy: str | None = None,
    adapt_rig: Callable[[SimRig], Rig] | None = None,
    overwrite: bool = False,
) -> dict[str, Any]:
    """Run the campaign of ``scenario`` in the twin and write its outputs in ``out_dir``.

    Args:
        scenario: a scenario or the path of its file.
        out_dir: where ``log.mcap``, ``results.json``, ``cameras/``, ``figures/`` and
            ``report.md`` go (created if needed). It must be empty (or a folder that
            holds only what is written here) unless ``overwrite``: see
            :func:`twin.outputs.claim_folder`.
        fidelity: ``render`` or ``geometric``.
        seed: the run's root seed (default: the scenario's).
        noise: False switches every noise source off (:meth:`Scenario.without_noise`).
        progress: called with each :class:`Progress` of the campaign.
        report: write the figures and ``report.md``.
        advertised_noise: the noise the simulated instrument reports to the campaign
            (default: the noise it simulates); an error budget simulates one source alone
            while the campaign weighs its data as in the real run.
        strategy: the campaign's strategy by name (default: the scenario's
            ``campaign.strategy``); see :data:`twin.campaign.STRATEGIES`.
        adapt_rig: given the simulated rig (its devices and its world), returns the rig the
            campaign runs with: the devices wrapped to inject a fault, say
            (:mod:`twin.hal.wrappers`). The recorder wraps what it returns.
        overwrite: replace what an earlier run wrote in ``out_dir``.

    Returns:
        The results (also in ``results.json``).

    Raises:
        ValueError: an unknown fidelity or strategy, a seed out of range (nothing is
            written).
        twin.outputs.OutputError: ``out_dir`` cannot be used (nothing is written).
    """
    if fidelity not in FIDELITIES:
        raise ValueError(f"fidelity must be one of {FIDELITIES}, got {fidelity!r}")
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    if seed is not None:
        sc = sc.model_copy(update={"seed": check_seed(seed)})
    if not noise:
        sc = sc.without_noise()
    chosen = strategy_for(sc, strategy)
    arguments = {
        "scenario": sc.source or sc.name,
        "fidelity": fidelity,
        "seed": sc.seed,
        "noise": noise,
        "strategy": chosen.name,
    }
    folder = claim_folder(Path(out_dir), "run", RUN_OUTPUTS, arguments, overwrite=overwrite)
    out = folder.path
    log_path = out / "log.mcap"
    t0 = time.perf_counter()
    with McapRecorder(log_path) as log:
        log.record(
            META,
            {
                "scenario": sc.name,
                "scenario_file": sc.source,
                "fidelity": fidelity,
                "seed": sc.seed,
                "noise": noise,
                "strategy": chosen.name,
                "started": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            },
            0.0,
        )
        world = build_world(sc, markers=built_markers(sc))
        sim = build_sim_rig(world, fidelity, advertised=advertised_noise, truth=log)
        try:
            devices = sim.rig if adapt_rig is None else adapt_rig(sim)
            rig = recorded(devices, log)
            Campaign(rig, sc, log, progress, chosen).run()
            wall = time.perf_counter() - t0
            timings = dict(sim.rig.timings)
            if "observe" in timings:
                timings["detection"] = max(timings.pop("observe") - timings.get("render", 0.0), 0.0)
            timings["other"] = max(wall - sum(timings.values()), 0.0)
            log.record(
                SUMMARY,
                {"wall_time_s": wall, "timings_s": timings},
                rig.clock.now(),
            )
        finally:
            sim.close()
    results = results_from_log(read_log(log_path).messages, sc.campaign.pixel_size_mm)
    write_text_atomic(out / "results.json", json.dumps(results, indent=2, allow_nan=False) + "\n")
    write_cameras(results, read_log(log_path).messages, out / "cameras")
    if report:
        write_report(sc, results, out)
    folder.finished(calibrations=len(results["calibrations"]))
    return results


RUN_OUTPUTS = ("log.mcap", "results.json", "cameras", "figures", "report.md")
"""What a run writes in its folder (and clears there with ``overwrite``)."""


MARKER_STREAM = 4
"""Spawn key of the random stream of the marker assemblies' surveying errors."""


def built_markers(scenario: Scenario) -> dict[str, MarkerAssembly]:
    """Each child's marker assembly as built: the scenario's geometry with an error of
    ``noise.marker_geometry_m`` on every coordinate, drawn from the scenario's seed (none
    when that is 0)."""
    sigma = scenario.noise.marker_geometry_m
    if sigma == 0.0:
        return {}
    nominal = scenario.marker.assembly()
    rng = np.random.default_rng(np.random.SeedSequence(scenario.seed, spawn_key=(MARKER_STREAM,)))
    out = {}
    for child in scenario.robots.children:
        out[child.name] = MarkerAssembly(
            cubes_body=nominal.cubes_body + sigma * rng.standard_normal(nominal.cubes_body.shape),
            leds_body=nominal.leds_body + sigma * rng.standard_normal(nominal.leds_body.shape),
        )
    return out


def write_cameras(results: dict[str, Any], messages: Any, folder: Path) -> list[Path]:
    """Each calibrated camera as ``NAME_visitK.json``, ``.yaml`` (OpenCV) and
    ``.camera_info.yaml`` (ROS) in ``folder``."""
    from twin.campaign.records import CALIBRATION

    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for m in messages:
        if m.topic != CALIBRATION:
            continue
        camera = camera_from_dict(m.data["camera_model"], "calibration")
        stem = f"{m.data['camera']}_visit{m.data['visit']}"
        for suffix in (".json", ".yaml", ".camera_info.yaml"):
            path = folder / f"{stem}{suffix}"
            save_camera(camera, path, name=m.data["camera"])
            written.append(path)
    return written
