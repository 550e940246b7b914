"""A site's plan that runs: one noise-free geometric run of the plan, and where it drops a
visit, the plan made again around what failed, cheapest repair first, until every camera
is calibrated or the repairs run out.

The run's first dropped visit is diagnosed (:func:`trial_run`): which visit, whether its
travel or its data failed, where (the route's point the abort names, else the parent's
last fix, else the station) and why (the skipped visit's reason and message). The repairs
for it, in the order tried:

1. data that failed at the station, or a travel that failed within a leg of it: another
   station for the camera, :data:`twin.planning.stations.AVOID_RADIUS` or more from the
   failed one (:func:`twin.planning.stations.choose_station`'s ``avoid``);
2. a travel that failed on the way: shorter CPS legs (``campaign.formation.step`` halved,
   down to :data:`SHORTEST_STEP`), then another station for the camera;
3. another visit order, unless the user gave one: the failed camera first, then the
   tour reversed.

A repair is kept when its run calibrates more cameras (then more visits) than the best
plan so far; the next repairs start from the best. Attempts and time are bounded
(:func:`repair_plan`).
"""

from __future__ import annotations

import dataclasses
import re
import tempfile
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.planning.floor_map import MapError
from twin.planning.site import SitePlan
from twin.scenario import Scenario

SHORTEST_STEP = 1.25
"""Shortest CPS step a repair tries, m (the default step, 5 m, halved twice)."""

ATTEMPTS = 6
"""Repairs tried at most by default (each a noise-free geometric run of a new plan)."""

SECONDS = 120.0
"""No repair starts after this many seconds of repairing, by default."""

LEG_AT = re.compile(r"\bs = (-?\d+(?:\.\d+)?) m\b")
"""The route's arc length an aborted travel names (``no formation for the leg to s = 22.8 m``)."""


@dataclass(frozen=True)
class Failed:
    """Where and why a run first dropped a visit.

    Attributes:
        camera, visit: the visit (its number among the camera's visits).
        stage: ``travel`` (the parent did not reach the station) or ``station`` (the data
            there gave no calibration).
        why: the skipped visit's ``reason: message``.
        place: (2,) where it failed in W, m: the route's point the abort names, else the
            parent's last fix (travel), else the station.
        station: (2,) the visit's station in W, m.
    """

    camera: str
    visit: int
    stage: str
    why: str
    place: NDArray[np.float64]
    station: NDArray[np.float64]


@dataclass(frozen=True)
class TrialRun:
    """One noise-free geometric run of a plan.

    Attributes:
        predicted_mm: each calibrated camera's predicted world-frame position error (RMS mm
            over its better visit) from the covariance the campaign propagates with the
            scenario's noise.
        calibrated: the cameras calibrated at least once. visits: the visits calibrated.
        dropped: the visits dropped (:func:`twin.run.campaign_run.dropped_visits`).
        failed: the first of them diagnosed; None if none was dropped.
        missed: why each camera not calibrated was not (``reason: message`` of its first
            dropped visit, or ``not visited``).
    """

    predicted_mm: dict[str, float]
    calibrated: frozenset[str]
    visits: int
    dropped: list[dict[str, Any]]
    failed: Failed | None
    missed: dict[str, str]

    @property
    def score(self) -> tuple[int, int]:
        """What a repair must raise: (cameras calibrated, visits calibrated)."""
        return len(self.calibrated), self.visits


def trial_run(scenario: Scenario) -> TrialRun:
    """Run ``scenario`` once at the geometric fidelity with every noise source off (the
    campaign told the scenario's noise, so that it propagates the covariance the
    predictions come from), and read what it gave (see :class:`TrialRun`)."""
    from twin.campaign.records import PARENT_FIX, STAGE
    from twin.montecarlo.prediction import predictions_from_log
    from twin.record import read_log
    from twin.run.campaign_run import dropped_visits
    from twin.run.runner import run_scenario

    with tempfile.TemporaryDirectory() as tmp:
        results = run_scenario(
            scenario,
            tmp,
            fidelity="geometric",
            noise=False,
            advertised_noise=scenario.noise,
            report=False,
            overwrite=True,
            cameras=False,
            foxglove=False,
        )
        messages = read_log(Path(tmp) / "log.mcap").messages
    pixel = {c.name: scenario.projected_led_px(c.name) for c in scenario.cameras}
    predictions, _ = predictions_from_log(messages, pixel)
    predicted: dict[str, float] = {}
    for p in predictions:
        mm = 1e3 * p.rms_m
        predicted[p.camera] = min(predicted.get(p.camera, mm), mm)
    calibrated = frozenset(str(c["camera"]) for c in results["calibrations"])
    dropped = dropped_visits(results, scenario)
    missed: dict[str, str] = {}
    for d in dropped:
        if d["camera"] not in calibrated and d["camera"] not in missed:
            missed[d["camera"]] = _why(d)
    for camera in scenario.cameras:
        if camera.name not in calibrated and camera.name not in missed:
            missed[camera.name] = "not visited"
    stages = [m.data for m in messages if m.topic == STAGE]
    fixes = [m.data for m in messages if m.topic == PARENT_FIX]
    failed = _first_failure(scenario, dropped, stages, fixes)
    return TrialRun(predicted, calibrated, len(results["calibrations"]), dropped, failed, missed)


def _why(dropped: Mapping[str, Any]) -> str:
    reason, message = dropped["reason"], dropped["message"]
    return f"{reason}: {message}" if message else str(reason)


def _first_failure(
    scenario: Scenario,
    dropped: list[dict[str, Any]],
    stages: list[Mapping[str, Any]],
    fixes: list[Mapping[str, Any]],
) -> Failed | None:
    """The first dropped visit the run failed at itself (not one an abort before it left
    unmade), diagnosed."""
    from twin.campaign.plan.route import RoutePath

    for d in dropped:
        if d["reason"] == "campaign_aborted" and d["message"].startswith(
            "the campaign was aborted"
        ):
            continue  # not made: the abort happened on an earlier visit (or before any)
        station = np.asarray(d["station"], dtype=float)
        mine = [s for s in stages if s["camera"] == d["camera"] and s["visit"] == d["visit"]]
        stage = "station" if mine and mine[-1]["stage"] == "station" else "travel"
        if d["reason"] == "station_unreachable":
            stage = "travel"
        place = station
        if stage == "travel":
            at = LEG_AT.search(d["message"])
            if at is not None:
                place = RoutePath(scenario.route.waypoints).at(float(at.group(1)))
            elif d["reason"] != "station_unreachable" and fixes:
                place = np.asarray(fixes[-1]["translation"], dtype=float)[:2]
        return Failed(d["camera"], d["visit"], stage, _why(d), place, station)
    return None


@dataclass(frozen=True)
class Fix:
    """What the repairs changed in a plan.

    Attributes:
        avoid: by camera, places in the map's frame its station keeps away from, m.
        step: the CPS step (``campaign.formation.step``), m; None: the scenario's default.
        order: the visits' cameras in order; None: the planner's.
    """

    avoid: dict[str, tuple[tuple[float, float], ...]] = field(default_factory=dict)
    step: float | None = None
    order: tuple[str, ...] | None = None

    def key(self) -> tuple[Any, ...]:
        """What tells two fixes apart (the repairs already tried)."""
        return (tuple(sorted(self.avoid.items())), self.step, self.order)


@dataclass(frozen=True)
class Attempt:
    """One repair tried.

    Attributes:
        what: the repair, in words (places in the map's frame). fix: the plan's changes
            with it. run: its run (None if the plan could not be made). kept: whether it
            became the best plan. error: why the plan could not be made ("" if it was).
        cause: the failure it repairs, ``CAMERA visit N (reason: message)``.
    """

    what: str
    fix: Fix
    run: TrialRun | None
    kept: bool
    error: str = ""
    cause: str = ""


@dataclass(frozen=True)
class Repaired:
    """The best plan found and how it was found.

    Attributes:
        plan: the plan. scenario: its scenario. run: its trial run. fix: its changes.
        attempts: the repairs tried, in order.
    """

    plan: SitePlan
    scenario: Scenario
    run: TrialRun
    fix: Fix
    attempts: tuple[Attempt, ...]


Planner = Callable[[Fix], tuple[SitePlan, Scenario]]
"""Plans the site with a fix (raises MapError if it cannot)."""


def repair_plan(
    planner: Planner,
    *,
    default_step: float,
    fixed_order: bool,
    attempts: int = ATTEMPTS,
    seconds: float = SECONDS,
    tried: Callable[[Attempt], None] | None = None,
    run: Callable[[Scenario], TrialRun] | None = None,
) -> Repaired:
    """Plan with no fix, run it, and repair it while it drops a visit (see the module).

    Args:
        planner: plans the site with a fix; a MapError with no fix is raised to the caller,
            with a fix the repair counts as tried and failed.
        default_step: the CPS step of a plan with no step fixed, m.
        fixed_order: the user gave the visits' order: it is kept.
        attempts: repairs tried at most (0: the plan as made). seconds: no repair starts
            after this long, s.
        tried: called with each repair as it ends. run: runs a plan (default
            :func:`trial_run`).
    """
    run = run or trial_run
    fix = Fix()
    plan, scenario = planner(fix)
    best = Repaired(plan, scenario, run(scenario), fix, ())
    done: set[tuple[Any, ...]] = {fix.key()}
    log: list[Attempt] = []
    t0 = time.perf_counter()
    while len(log) < attempts and time.perf_counter() - t0 < seconds:
        failed = best.run.failed
        if failed is None:
            break
        options = [
            (what, f)
            for what, f in _repairs(failed, best, default_step, fixed_order)
            if f.key() not in done
        ]
        if not options:
            break
        what, f = options[0]
        done.add(f.key())
        cause = f"{failed.camera} visit {failed.visit} ({failed.why})"
        try:
            plan, scenario = planner(f)
        except MapError as exc:
            attempt = Attempt(what, f, None, False, str(exc), cause)
        else:
            trial = run(scenario)
            kept = trial.score > best.run.score
            attempt = Attempt(what, f, trial, kept, cause=cause)
            if kept:
                best = Repaired(plan, scenario, trial, f, ())
        log.append(attempt)
        if tried is not None:
            tried(attempt)
    return dataclasses.replace(best, attempts=tuple(log))


def _repairs(
    failed: Failed, best: Repaired, default_step: float, fixed_order: bool
) -> list[tuple[str, Fix]]:
    """The repairs for ``failed`` from the best plan so far, cheapest first: (what, fix)."""
    fix, plan = best.fix, best.plan
    cam = failed.camera
    here = plan.pose.world2map(failed.place)
    station = plan.pose.world2map(failed.station)
    avoid = (*fix.avoid.get(cam, ()), (round(float(station[0]), 2), round(float(station[1]), 2)))
    another = (
        f"another station for {cam}, away from ({station[0]:.2f}, {station[1]:.2f}) (map frame)",
        dataclasses.replace(fix, avoid={**fix.avoid, cam: avoid}),
    )
    step = fix.step or default_step
    shorter = []
    while step / 2 >= SHORTEST_STEP - 1e-9:
        step /= 2
        shorter.append(
            (
                f"shorter legs ({step:g} m) for the travel that failed near "
                f"({here[0]:.2f}, {here[1]:.2f}) (map frame)",
                dataclasses.replace(fix, step=step),
            )
        )
    orders = []
    first = (cam, *(c for c in plan.order if c != cam))
    backwards = tuple(reversed(plan.order))
    for what, order in (
        (f"another visit order ({cam} first)", first),
        ("the visits in reverse order", backwards),
    ):
        if not fixed_order and order != plan.order:
            orders.append((what, dataclasses.replace(fix, order=order)))
    near = float(np.linalg.norm(failed.place - failed.station)) <= default_step
    if failed.stage == "station" or near:
        return [another, *shorter, *orders]
    return [*shorter[:1], another, *shorter[1:], *orders]
