"""``twin site``: a map and a cameras file in, a validated scenario and its figure out."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from twin.outputs import write_text_atomic
from twin.planning.floor_map import MapError
from twin.planning.maps import load_map
from twin.planning.repair import ATTEMPTS, SECONDS, Attempt, Fix, TrialRun, repair_plan
from twin.planning.site import SitePlan, plan_site, read_cameras
from twin.scenario import Scenario
from twin.scenario.errors import ScenarioError
from twin.scenario.loader import scenario_from_dict
from twin.scenario.schema import FormationSettings


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
            (the skipped visit's reason and message, and where it failed in the map's
            frame); empty when not predicted.
        repairs: the repairs tried on the plan, in order (:mod:`twin.planning.repair`);
            the plan written is the best.
    """

    path: Path
    figure: Path
    scenario: Scenario
    plan: SitePlan
    predicted_mm: dict[str, float]
    route_length_m: float
    not_calibrated: dict[str, str] = field(default_factory=dict)
    repairs: tuple[Attempt, ...] = ()


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
    repairs: int = ATTEMPTS,
    repair_seconds: float = SECONDS,
    tried: Callable[[Attempt], None] | None = None,
    ceiling_height: float | None = None,
    map_options: dict[str, Any] | None = None,
) -> WrittenSite:
    """Plan a site and write its scenario (TOML) and figure.

    ``data_stops`` is the scenario's ``campaign.data_stops``: ``accuracy`` plans the child's
    data points for the camera's accuracy (:mod:`twin.campaign.plan.accurate_stops`).
    ``ceiling_height`` goes to :func:`plan_site`, ``map_options`` to the map's reader
    (:func:`twin.planning.maps.load_map`).

    With ``predict``, the plan is run once noise-free at the geometric fidelity, and where
    that run drops a visit the plan is repaired (:func:`twin.planning.repair.repair_plan`:
    at most ``repairs`` repairs, none started after ``repair_seconds``; ``tried`` is called
    with each); the best plan is written.

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
    floor = load_map(map_path, **(map_options or {}))
    cameras = read_cameras(cameras_path)
    map_ref = _relative(map_path, out.parent)

    def planner(fix: Fix) -> tuple[SitePlan, Scenario]:
        plan = plan_site(
            floor,
            cameras,
            name=name or _name(out.stem),
            start=start,
            visits=visits if fix.order is None else fix.order,
            return_to_start=return_to_start,
            resolution=resolution,
            map_file=map_ref,
            avoid=fix.avoid,
            ceiling_height=ceiling_height,
        )
        campaign: dict[str, Any] = {}
        if data_stops != "all_leds":
            campaign["data_stops"] = data_stops
        if fix.step is not None:
            campaign["formation"] = {"step": fix.step}
        if campaign:
            plan.scenario["campaign"] = campaign
        try:
            scenario = scenario_from_dict(plan.scenario, file=out)
        except ScenarioError as exc:
            raise MapError(floor.source, f"the planned scenario does not validate: {exc}") from None
        return plan, scenario

    if predict:
        repaired = repair_plan(
            planner,
            default_step=FormationSettings().step,
            fixed_order=visits is not None,
            attempts=repairs,
            seconds=repair_seconds,
            tried=tried,
        )
        plan, scenario, attempts = repaired.plan, repaired.scenario, repaired.attempts
        predicted = repaired.run.predicted_mm
        missed = _where_missed(repaired.run, plan)
    else:
        (plan, scenario), attempts = planner(Fix()), ()
        predicted, missed = {}, {}
    out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out, _header(map_ref) + tomli_w.dumps(plan.scenario))
    from twin.planning.figure import plan_figure

    figure = plan_figure(scenario, out.with_suffix(".plan.png"), predicted)
    route = np.asarray(scenario.route.waypoints)
    length = float(np.sum(np.linalg.norm(np.diff(route, axis=0), axis=1)))
    return WrittenSite(out, figure, scenario, plan, predicted, length, missed, attempts)


def _where_missed(run: TrialRun, plan: SitePlan) -> dict[str, str]:
    """Why each camera ``run`` did not calibrate was not, the place its visit failed named
    in the map's frame."""
    out = dict(run.missed)
    failed = run.failed
    if failed is not None and failed.camera in out:
        x, y = plan.pose.world2map(failed.place)
        what = "travel to its station" if failed.stage == "travel" else "data at its station"
        out[failed.camera] += f" (the {what} failed at ({x:.2f}, {y:.2f}) in the map's frame)"
    return out


def _relative(path: Path, folder: Path) -> str:
    """``path`` relative to ``folder`` (``../maps/floor.yaml``), so that the scenario and its
    map move together; absolute where no relative path leads there (another drive)."""
    try:
        return os.path.relpath(path.resolve(), folder.resolve())
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
        "# ([site] map_pose gives it in the map's frame). The blocked floor is the map's,\n"
        "# laid on a grid as boxes when the scenario is read ([space.map]: the map must keep\n"
        "# its sha256); each station sees its camera's floor view.\n\n"
    )
