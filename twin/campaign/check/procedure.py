"""The check's procedure: the campaign's own steps, a few stops per camera, no calibration.

The campaign (:class:`twin.campaign.Campaign`) runs with the check's strategy
(:class:`twin.campaign.check.strategy.CheckStrategy`) and a collection that calibrates
nothing (:class:`twin.campaign.check.collection.CheckCollection`): the parent stands at
its first station, which defines W, and the child takes a handful of LED points for each
camera the first station sees; the group then travels by CPS to the first visit station
of each other camera and takes its points there. Each camera's points are then tested
against its calibrated model and re-posed (:func:`twin.campaign.check.assessment.assess`).

The first station must be the calibration's: the check's W is the parent's instrument
frame there, and the calibrated cameras are in the calibration run's W.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from calib.camera import TsaiCamera
from twin.campaign.check.assessment import CameraCheck, assess
from twin.campaign.check.collection import CheckCollection
from twin.campaign.check.consistency import DEFAULT_FALSE_ALARM_RATE, check_false_alarm_rate
from twin.campaign.check.covariance import MIN_PIXEL_SIGMA
from twin.campaign.check.gathering import PointGatherer
from twin.campaign.check.strategy import CheckStrategy
from twin.campaign.journal import Progress
from twin.campaign.procedure import Campaign
from twin.campaign.strategies import strategy_named
from twin.campaign.strategy import Strategy
from twin.hal.recording import Recorder, recorded
from twin.hal.rig import Rig
from twin.scenario.schema import Scenario

DEFAULT_STOPS = 5
"""The child's stops per camera (``twin check --stops``): 20 LED points with four LEDs,
against a calibration's 70."""

MIN_STOPS = 2
"""Fewest stops that can re-pose a camera: one stop's LEDs stand on one vertical line."""

MAX_STOPS = 50
"""Most stops per camera: beyond it, calibrate the camera again (``twin run``)."""


@dataclass
class CheckOutcome:
    """What the check found.

    Attributes:
        checks: the verdict on each camera that was checked, by name.
        unchecked: why each other camera was not checked (``no_station``,
            ``too_few_points``, ``station_unreachable``, ``not_reached``,
            ``bad_calibration``: with words), by name.
        station: where each checked camera's data were taken (``first station`` or
            ``visit station (x, y)``), by name.
        failures, events: the campaign's counts by kind (as ``twin run`` reports them).
        travelled: the parent's travel, m.
    """

    checks: dict[str, CameraCheck] = field(default_factory=dict)
    unchecked: dict[str, str] = field(default_factory=dict)
    station: dict[str, str] = field(default_factory=dict)
    failures: Counter = field(default_factory=Counter)
    events: Counter = field(default_factory=Counter)
    travelled: float = 0.0


def check_stops(stops: int) -> int:
    """``stops`` if it is a whole number from :data:`MIN_STOPS` to :data:`MAX_STOPS`;
    ValueError naming it otherwise."""
    if isinstance(stops, bool) or int(stops) != stops or not MIN_STOPS <= stops <= MAX_STOPS:
        raise ValueError(
            f"the stops per camera must be a whole number from {MIN_STOPS} to {MAX_STOPS}, "
            f"got {stops!r}"
        )
    return int(stops)


def check_min_pixel_sigma(sigma_px: float) -> float:
    """``sigma_px`` if it is a finite number above 0 and at most 10 px; ValueError naming
    it otherwise."""
    value = float(sigma_px)
    if not (np.isfinite(value) and 0.0 < value <= 10.0):
        raise ValueError(
            f"the least pixel standard deviation must lie in (0, 10] px, got {sigma_px!r}"
        )
    return value


def check_cameras(
    rig: Rig,
    scenario: Scenario,
    calibrated: Mapping[str, TsaiCamera],
    recorder: Recorder | None = None,
    *,
    covariances: Mapping[str, NDArray[np.float64]] | None = None,
    stops: int = DEFAULT_STOPS,
    false_alarm_rate: float = DEFAULT_FALSE_ALARM_RATE,
    min_pixel_sigma: float = MIN_PIXEL_SIGMA,
    strategy: Strategy | None = None,
    progress: Callable[[Progress], None] | None = None,
) -> CheckOutcome:
    """Check whether each calibrated camera is still where its calibration says.

    Args:
        rig: the devices, the parent at its first station (the calibration's W).
        scenario: the plan and the map (the cameras' nominal poses, the route, the visits).
        calibrated: each camera to check, by name: its calibrated model, pose in W.
        recorder: where every reading and the campaign's records go (None: nowhere).
        covariances: each calibrated camera's (11, 11) covariance
            (:data:`calib.camera_covariance.CAMERA_PARAMETERS`), by name; a camera
            without one is taken as exact.
        stops: the child's stops per camera (four LED points each).
        false_alarm_rate: the chi-square test's, in (0, 1).
        min_pixel_sigma: the least standard deviation of an LED's pixel coordinate, px
            (:data:`twin.campaign.check.covariance.MIN_PIXEL_SIGMA`).
        strategy: the campaign's strategy for travel and stops (default: the scenario's).
        progress: called with each :class:`Progress` of the campaign.

    Raises:
        ValueError: a camera the scenario lacks, a bad number of stops or false-alarm
            rate (before anything moves).
    """
    stops = check_stops(stops)
    alpha = check_false_alarm_rate(false_alarm_rate)
    sigma = check_min_pixel_sigma(min_pixel_sigma)
    names = [c.name for c in scenario.cameras]
    for name in calibrated:
        if name not in names:
            raise ValueError(
                f"camera {name!r} is not in scenario {scenario.name!r}; its cameras: "
                + ", ".join(names)
            )
    target = stops * len(scenario.marker.leds)
    settings = scenario.campaign.model_copy(
        update={"reference_points": target, "station_points": target, "min_points": target}
    )
    sc = scenario.model_copy(update={"campaign": settings})
    gatherer = PointGatherer(recorder)
    plan = CheckStrategy(strategy or strategy_named(sc.campaign.strategy), list(calibrated))
    campaign = Campaign(recorded(rig, gatherer), sc, gatherer, progress, plan)
    campaign.collection = CheckCollection(
        campaign.rig,
        campaign.travel,
        campaign.journal,
        campaign.settings,
        campaign.collection.sequence,
    )
    done = campaign.run()
    outcome = CheckOutcome(failures=done.failures, events=done.events, travelled=done.travelled)
    skipped = {s.camera: f"{s.reason}: {s.message}" for s in done.skipped}
    for name in plan.no_station:
        outcome.unchecked[name] = (
            "no_station: the first station does not see it and no visit of the scenario names it"
        )
    for name, camera in calibrated.items():
        if name in outcome.unchecked:
            continue
        points = gatherer.points.get(name, [])
        if len(points) < MIN_STOPS:
            outcome.unchecked[name] = skipped.get(name) or (
                f"too_few_points: {len(points)} stops gave LED points, {MIN_STOPS} needed"
                if points or name in plan.from_first
                else "not_reached: the campaign ended before its station (see the failures)"
            )
            continue
        try:
            cov = (covariances or {}).get(name)
            outcome.checks[name] = assess(name, camera, points, alpha, cov, sigma)
        except ValueError as exc:
            outcome.unchecked[name] = f"bad_calibration: {exc}"
            continue
        if name in plan.from_first:
            outcome.station[name] = "first station"
        else:
            visit = next(v for v in plan.visits if v.camera == name)
            x, y = visit.station
            outcome.station[name] = f"visit station ({x:g}, {y:g})"
    return outcome
