"""Run the calibration campaign of a scenario in the twin, and write everything it gives.

This is the one place where the backend is chosen: a simulated rig at the ``render`` or
``geometric`` fidelity (:mod:`twin.sim.rig`) is built on the scenario's world, wrapped so
that every reading goes to ``DIR/log.mcap`` as it arrives, and handed to
:class:`twin.campaign.Campaign` with its strategy. The simulation records its own truth
(camera poses, the instrument's true pose at every CPS fix) beside the readings, under
``/truth/`` (:mod:`twin.truth`). The results are then computed from the log alone
(:func:`twin.campaign.log_results.results_from_log`), by :mod:`twin.run.campaign_run`:

- ``DIR/results.json``, ``DIR/cameras/`` (JSON, OpenCV YAML, ROS camera_info per
  calibration), ``DIR/figures/`` and ``DIR/report.md``.

:func:`check_scenario` builds the same simulated rig for ``twin check``
(:mod:`twin.run.check_run`): the calibrated cameras checked where the twin's world holds them.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

import twin.sim  # noqa: F401  (headless rendering is configured before MuJoCo loads)
from twin.campaign import Progress
from twin.campaign.check import DEFAULT_FALSE_ALARM_RATE, DEFAULT_STOPS, MIN_PIXEL_SIGMA
from twin.campaign.strategies import strategy_for
from twin.campaign.strategy import Strategy
from twin.hal.recording import Recorder
from twin.hal.rig import Rig
from twin.instruments.marker import MarkerAssembly
from twin.record import McapRecorder
from twin.run.campaign_run import RUN_OUTPUTS, run_campaign, write_cameras
from twin.run.check_run import run_check
from twin.scenario import Scenario, load_scenario
from twin.scenario.limits import check_seed
from twin.scenario.schema import Noise
from twin.sim.rig import FIDELITIES, SimRig, build_sim_rig
from twin.sim.world import build_world

if TYPE_CHECKING:
    from twin.record.foxglove.live import LiveServer


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
    strategy: Strategy | str | None = None,
    adapt_rig: Callable[[SimRig], Rig] | None = None,
    overwrite: bool = False,
    cameras: bool = True,
    foxglove: bool = True,
    live: LiveServer | None = None,
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
        strategy: the campaign's strategy, built (one instance serves one run) or by name
            (default: the scenario's ``campaign.strategy``); see
            :data:`twin.campaign.STRATEGIES`.
        adapt_rig: given the simulated rig (its devices and its world), returns the rig the
            campaign runs with: the devices wrapped to inject a fault, say
            (:mod:`twin.hal.wrappers`). The recorder wraps what it returns.
        overwrite: replace what an earlier run wrote in ``out_dir``.
        cameras: write ``cameras/`` (a Monte-Carlo trial, which reads only the results and
            the log, does not).
        foxglove: write Foxglove's channels in the log beside the records (a Monte-Carlo
            trial, whose log no one opens, does not).
        live: also serve the log's Foxglove channels on this server as they are written
            (the log and the results are the same without it).

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

    def open_rig(log: McapRecorder) -> tuple[Rig, Callable[[], None], dict[str, float]]:
        world = build_world(sc, markers=built_markers(sc))
        sim = build_sim_rig(world, fidelity, advertised=advertised_noise, truth=log)
        try:
            devices = sim.rig if adapt_rig is None else adapt_rig(sim)
        except BaseException:
            sim.close()
            raise
        return devices, sim.close, sim.rig.timings

    meta = {"fidelity": fidelity, "seed": sc.seed, "noise": noise}
    return run_campaign(
        sc,
        out_dir,
        arguments,
        meta,
        open_rig,
        chosen,
        progress,
        report,
        overwrite,
        cameras,
        foxglove=foxglove,
        live=live,
    )


def check_scenario(
    scenario: Scenario | str | Path,
    cameras_dir: str | Path,
    out_dir: str | Path,
    *,
    fidelity: str = "render",
    seed: int | None = None,
    stops: int = DEFAULT_STOPS,
    false_alarm_rate: float = DEFAULT_FALSE_ALARM_RATE,
    min_pixel_sigma: float = MIN_PIXEL_SIGMA,
    progress: Callable[[Progress], None] | None = None,
    strategy: Strategy | str | None = None,
    overwrite: bool = False,
) -> dict[str, Any]:
    """Check in the twin whether the cameras a run calibrated (``cameras_dir``) are still
    where their calibrations say; write ``log.mcap``, ``check.json`` and the moved cameras'
    files in ``out_dir`` (:func:`twin.run.check_run.run_check`).

    The twin's world is the scenario's, ``faults.moved_cameras`` included: a camera moved
    there is where the check finds it.

    Args:
        scenario: a scenario or its file. cameras_dir: the ``cameras/`` folder a run wrote.
        out_dir: the check's folder. fidelity: ``render`` or ``geometric``.
        seed: the twin's seed, as ``twin run --seed`` (default: the scenario's): give the
            calibration run's, so that the world (the markers as built) is the same. The
            check's noise is drawn from streams of its own (:func:`check_noise_seed`).
        stops, false_alarm_rate, min_pixel_sigma: as
            :func:`twin.campaign.check.check_cameras`.
        progress, strategy, overwrite: as :func:`run_scenario`.

    Raises:
        ValueError: an unknown fidelity or strategy, a seed, stops or false-alarm rate out
            of range; twin.run.run_cameras.CamerasFolderError: a cameras folder that cannot
            be checked; twin.outputs.OutputError: ``out_dir`` cannot be used. Nothing is
            written for any of these.
    """
    if fidelity not in FIDELITIES:
        raise ValueError(f"fidelity must be one of {FIDELITIES}, got {fidelity!r}")
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    if seed is not None:
        sc = sc.model_copy(update={"seed": check_seed(seed)})
    chosen = strategy_for(sc, strategy)
    noise_seed = check_noise_seed(sc.seed)
    arguments = {
        "scenario": sc.source or sc.name,
        "cameras": str(cameras_dir),
        "fidelity": fidelity,
        "seed": sc.seed,
        "stops": stops,
        "false_alarm_rate": false_alarm_rate,
        "min_pixel_sigma": min_pixel_sigma,
        "strategy": chosen.name,
    }

    def open_rig(log: Recorder) -> tuple[Rig, Callable[[], None]]:
        world = build_world(sc, markers=built_markers(sc))
        sim = build_sim_rig(world, fidelity, seed=noise_seed, truth=log)
        return sim.rig, sim.close

    meta = {"fidelity": fidelity, "seed": sc.seed, "noise_seed": noise_seed}
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


CHECK_STREAM = 7
"""Spawn key of the root seed of a check's noise (:func:`check_noise_seed`)."""


def check_noise_seed(seed: int) -> int:
    """The root seed of the noise of a check in the twin whose world has seed ``seed``: a
    seed of its own, so that a check's instrument and LED noise is not the calibration
    run's (whose noise, keyed to what each shot measures, it would repeat where it
    measures the same places)."""
    state = np.random.SeedSequence(seed, spawn_key=(CHECK_STREAM,)).generate_state(1, np.uint64)
    return int(state[0] >> np.uint64(1))


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


__all__ = [
    "RUN_OUTPUTS",
    "built_markers",
    "check_noise_seed",
    "check_scenario",
    "run_scenario",
    "write_cameras",
]
