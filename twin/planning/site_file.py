"""``twin site``: a map and a cameras file in, a validated scenario and its figure out."""

from __future__ import annotations

import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import tomli_w

from twin.outputs import write_text_atomic
from twin.planning.floor_map import MapError
from twin.planning.maps import load_map
from twin.planning.site import SitePlan, plan_site, read_cameras
from twin.scenario import Scenario
from twin.scenario.errors import ScenarioError
from twin.scenario.loader import scenario_from_dict


@dataclass(frozen=True)
class WrittenSite:
    """What :func:`write_site` wrote.

    Attributes:
        path: the scenario file. figure: the plan's figure (``SITE.plan.png``).
        scenario: the scenario as loaded back. plan: the plan.
        predicted_mm: each camera's predicted world-frame position error (RMS over its
            visits' best, mm) from one geometric run; empty when not predicted.
        route_length_m: the parent's route, m.
        not_calibrated: the cameras that geometric run did not calibrate, each with why
            (the skipped visit's reason and message); empty when not predicted.
    """

    path: Path
    figure: Path
    scenario: Scenario
    plan: SitePlan
    predicted_mm: dict[str, float]
    route_length_m: float
    not_calibrated: dict[str, str] = field(default_factory=dict)


def write_site(
    map_path: str | Path,
    cameras_path: str | Path,
    out: str | Path,
    *,
    name: str | None = None,
    start: tuple[float, float, float] | None = None,
    visits: Sequence[str] | None = None,
    return_to_start: bool = False,
    resolution: float = 0.1,
    predict: bool = True,
    overwrite: bool = False,
    data_stops: str = "all_leds",
) -> WrittenSite:
    """Plan a site and write its scenario (TOML) and figure.

    ``data_stops`` is the scenario's ``campaign.data_stops``: ``accuracy`` plans the child's
    data points for the camera's accuracy (:mod:`twin.campaign.plan.accurate_stops`).

    Raises:
        MapError: a bad map, cameras file or plan; nothing is written.
        ValueError: ``out`` exists (without ``overwrite``) or is not a ``.toml`` file.
    """
    out = Path(out)
    if out.suffix != ".toml":
        raise ValueError(f"{out}: the scenario is written as TOML: give a .toml file")
    if out.exists() and not overwrite:
        raise ValueError(f"{out} exists: give --overwrite to replace it")
    map_path = Path(map_path)
    floor = load_map(map_path)
    cameras = read_cameras(cameras_path)
    map_ref = _relative(map_path, out.parent)
    plan = plan_site(
        floor,
        cameras,
        name=name or _name(out.stem),
        start=start,
        visits=visits,
        return_to_start=return_to_start,
        resolution=resolution,
        map_file=map_ref,
    )
    if data_stops != "all_leds":
        plan.scenario["campaign"] = {"data_stops": data_stops}
    try:
        scenario = scenario_from_dict(plan.scenario, file=out)
    except ScenarioError as exc:
        raise MapError(floor.source, f"the planned scenario does not validate: {exc}") from None
    predicted, missed = predicted_errors(scenario) if predict else ({}, {})
    out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out, _header(map_ref) + tomli_w.dumps(plan.scenario))
    from twin.planning.figure import plan_figure

    figure = plan_figure(scenario, out.with_suffix(".plan.png"), predicted)
    route = np.asarray(scenario.route.waypoints)
    length = float(np.sum(np.linalg.norm(np.diff(route, axis=0), axis=1)))
    return WrittenSite(out, figure, scenario, plan, predicted, length, missed)


def predicted_errors(scenario: Scenario) -> tuple[dict[str, float], dict[str, str]]:
    """Each camera's predicted world-frame position error, RMS mm, from one geometric run
    of ``scenario`` (the covariance the campaign propagates, :mod:`twin.montecarlo.
    prediction`; a camera calibrated twice keeps its better visit), and why that run
    calibrated none of a camera's visits (``reason: message`` of its first skipped visit)
    for each camera it did not calibrate."""
    from twin.montecarlo.prediction import predictions_from_log
    from twin.record import read_log
    from twin.report.reading import skipped_why
    from twin.runner import run_scenario

    with tempfile.TemporaryDirectory() as tmp:
        results = run_scenario(scenario, tmp, fidelity="geometric", report=False, overwrite=True)
        messages = read_log(Path(tmp) / "log.mcap").messages
    pixel = {c.name: scenario.projected_led_px(c.name) for c in scenario.cameras}
    predictions, _ = predictions_from_log(messages, pixel)
    out: dict[str, float] = {}
    for p in predictions:
        mm = 1e3 * p.rms_m
        out[p.camera] = min(out.get(p.camera, mm), mm)
    calibrated = {c["camera"] for c in results["calibrations"]}
    missed: dict[str, str] = {}
    for skipped in results["skipped_visits"]:
        camera = skipped["camera"]
        if camera not in calibrated and camera not in missed:
            missed[camera] = skipped_why(skipped)
    for camera in scenario.cameras:
        if camera.name not in calibrated and camera.name not in missed:
            missed[camera.name] = "not visited"
    return out, missed


def _relative(path: Path, folder: Path) -> str:
    try:
        return str(path.resolve().relative_to(folder.resolve()))
    except ValueError:
        return str(path.resolve())


def _name(stem: str) -> str:
    cleaned = "".join(ch if ch.isalnum() or ch == "_" else "_" for ch in stem)
    cleaned = cleaned if cleaned[:1].isalpha() else f"site_{cleaned}"
    return cleaned[:40]


def _header(map_ref: str) -> str:
    return (
        f"# Planned by twin site from the map {map_ref}.\n"
        "# Coordinates are in the world frame W: the parent's instrument frame at its start\n"
        "# ([site] map_pose gives it in the map's frame). The blocked floor is laid on a grid\n"
        "# as boxes (space.obstacles); each station sees its camera's floor view.\n\n"
    )
