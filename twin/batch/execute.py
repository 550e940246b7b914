"""The batch fidelity: a campaign's plan (:mod:`twin.batch.plan`) executed for T trials at
once, every measurement and every estimate an array over the trials.

Each trial has its own noise, drawn from its own seed in a fixed order (so that a trial
gives the same result alone or in any batch), and the noise sources of the geometric
fidelity:

- the robots' stopping error: each drive ends at the goal, moved by the base's error of
  localisation (where it truly stood against where it believed it stood) and by the
  scenario's stopping error; the standing children's creep while the parent drives;
- the marker assemblies' surveying error (each child's own, for the whole trial);
- the total station's distance, angle and pointing noise in its (tilted) frame, each shot
  levelled with its own noisy inclination reading, and rounded to the output resolution;
- the LED detection noise of the geometric fidelity (``noise.led_detection_px``) and the
  real camera's centroid error (``noise.led_centroid_px``).

The estimators are the campaign's (:mod:`twin.batch.estimators`): marker fits and centroids,
CPS with its joint covariance and consistency tests, LED positions from the marker's pose,
Tsai's calibration of every visit and the Table III metrics.

A data point holds the LEDs the camera found in the noise-free plan (:class:`twin.batch.
plan.Point`: all of them, or at stops chosen for accuracy those the stop shows);
the LEDs it did not find give no point and no pixel residual.

What the batch leaves out, which the geometric fidelity keeps: decisions taken again under
noise (a re-aim after a lost lock or a wrong prism; a stop where an LED left the image is
given up, as the campaign does, but not replaced by another: at a stop chosen for accuracy
only that LED is given up, an LED that came into view at a stop planned
without it is not used, and the stops are not planned again from the noisy estimates; a fix
that failed its consistency test is not measured again: such a trial keeps its estimate and
counts a failure), the faults of ``[faults]``, the check shots at a child placed earlier
(which only matter when it moved), the tilt of a child on a tilted floor patch (its marker
is moved in the plane), and the occlusion of an LED by an obstacle or a person (the plan's
stops were chosen in the clear; the trials' stopping errors move them a few centimetres).

The executor advances one step of the plan at a time for all its trials (:meth:`BatchRun.
step`), and :meth:`BatchRun.outcome` reads what the trials gave so far: a caller can run a
plan decision by decision (a CPS leg, a camera's data) and look at the state between them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.covariance import own_position_variance
from calib.rotation import rot_z
from twin.batch.estimators import (
    CpsStates,
    Estimators,
    Observations,
    ParentEstimates,
    found,
)
from twin.batch.network import NetworkRecorder
from twin.batch.plan import (
    BatchPlan,
    Calibrate,
    DataSetDone,
    Drive,
    Fix,
    Place,
    Point,
    RobotTruth,
)
from twin.batch.vectorised import Vectorised
from twin.instruments.marker import MarkerAssembly
from twin.instruments.marker_pose import survey_layout, survey_loading
from twin.instruments.noise import normalise_polar, polar_sigmas, quantise_polar
from twin.instruments.polar import cartesian2polar, polar2cartesian
from twin.instruments.tilt import level_points, tilt_from_orientation
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec
from twin.scenario.schema import Noise
from twin.sim.capture import in_image

BATCH_STREAM = 11
"""Spawn key of a trial's stream of the batch fidelity's noise."""

CREEP_BATCH_STREAM = 12
"""Spawn key of a trial's stream of the children's creep (drawn only when there is some)."""

FALSE_ALARM_RATE = 1e-4
"""The consistency tests' false-alarm rate, as the campaign's with a noisy instrument."""


class Draws:
    """Each trial's standard normal draws, handed out in a fixed order.

    Each trial's draws come from its own generator, in blocks; a generator gives the same
    sequence whatever the blocks, so a trial's noise depends on its seed alone, not on the
    batch, the chunk, how far ahead the draws were reserved, or which other trials drew
    at the same time (each trial keeps its own place in its sequence).

    Args:
        seeds: (T,) the trials' root seeds.
        count: draws each trial is expected to need (reserved at once; more are drawn as
            they are needed).
        stream: the spawn key of the trials' generators (a source with its own stream
            changes no other source's draws when it is switched on).
    """

    def __init__(self, seeds: Sequence[int], count: int, stream: int = BATCH_STREAM) -> None:
        self.stream = stream
        self._generators = [self._generator(seed) for seed in seeds]
        self.values = np.zeros((len(seeds), 0))
        self.used = np.zeros(len(seeds), dtype=np.intp)  # each trial's place in values
        self._reserve(count)

    def _generator(self, seed: int) -> np.random.Generator:
        return np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(self.stream,)))

    def _reserve(self, count: int) -> None:
        """Drop the draws taken and draw more: every trial then has ``count`` or more
        ahead (each trial's own sequence goes on where it stopped)."""
        left = self.values.shape[1] - self.used
        width = int(left.max(initial=0)) + count
        self.values = np.stack(
            [
                np.concatenate([row[start:], g.standard_normal(width - ahead)])
                for row, start, ahead, g in zip(
                    self.values, self.used, left, self._generators, strict=True
                )
            ]
        ).reshape(len(self._generators), width)
        self.used = np.zeros(len(self._generators), dtype=np.intp)

    def take(self, *shape: int, rows: NDArray[np.intp] | None = None) -> NDArray[np.float64]:
        """(T, *shape) the next draws of every trial, or (R, *shape) of the trials
        ``rows``."""
        n = math.prod(shape)
        used = self.used if rows is None else self.used[rows]
        if len(used) and int(used.max()) + n > self.values.shape[1]:
            self._reserve(max(n, 4096))
            used = self.used if rows is None else self.used[rows]
        start = int(used[0]) if len(used) else 0
        if rows is None and (used == start).all():
            out = self.values[:, start : start + n]
            self.used = self.used + n
        else:
            picked = np.arange(len(self.values)) if rows is None else rows
            out = self.values[picked[:, None], used[:, None] + np.arange(n)]
            self.used[picked] += n
        return out.reshape(len(used), *shape)

    def restart(self, rows: NDArray[np.intp], seeds: Sequence[int]) -> None:
        """Trials ``rows`` start again from ``seeds`` (their first draws next)."""
        width = self.values.shape[1]
        for k, seed in zip(rows, seeds, strict=True):
            self._generators[k] = self._generator(seed)
            self.values[k] = self._generators[k].standard_normal(width)
            self.used[k] = 0


def draws_needed(plan: BatchPlan, n_leds: int) -> int:
    """How many normal draws one trial of ``plan`` takes."""
    per_shot = 3 + 2  # polar noise, inclination reading
    marker = len(plan.children) * (3 + n_leds) * 3
    count = marker
    for step in plan.steps:
        if isinstance(step, Drive):
            count += 3
        elif isinstance(step, Place):
            count += 3 * per_shot
        elif isinstance(step, Fix):
            count += 3 * per_shot * len(step.children)
        elif isinstance(step, Point):
            count += 2 * n_leds
    return count


def _compose(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """(T, 3) planar poses a (x) b: b expressed in the frame of a."""
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    return np.column_stack(
        [
            a[:, 0] + c * b[:, 0] - s * b[:, 1],
            a[:, 1] + s * b[:, 0] + c * b[:, 1],
            a[:, 2] + b[:, 2],
        ]
    )


def _inverse(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """(T, 3) inverse planar poses."""
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    return np.column_stack([-(c * a[:, 0] + s * a[:, 1]), s * a[:, 0] - c * a[:, 1], -a[:, 2]])


@dataclass
class _Robot:
    """A robot in T trials: where it truly stands and where it believes it stands (planar,
    (T, 3)), and each trial's stop in the noise-free plan (``nominal``: its pose, its
    marker's cubes and LEDs (a child), its instrument's centre, orientation and tilt (the
    parent), each (T, ...))."""

    true: NDArray[np.float64]
    believed: NDArray[np.float64]
    nominal: dict[str, NDArray[np.float64]]
    _stops: dict[int, tuple[RobotTruth, dict[str, NDArray[np.float64]]]] = field(
        default_factory=dict
    )

    @classmethod
    def at(cls, truth: RobotTruth, trials: int) -> _Robot:
        pose = np.repeat(truth.pose[None], trials, axis=0)
        return cls(pose.copy(), pose.copy(), _nominal(truth, trials))

    def stopped(self, truths: Sequence[RobotTruth], rows: NDArray[np.intp] | slice) -> None:
        """The trials ``rows`` stopped at ``truths`` (one for all, or one a row)."""
        stops = [self._stop(t) for t in truths]
        for name, values in self.nominal.items():
            values[rows] = stops[0][name] if len(stops) == 1 else [s[name][0] for s in stops]

    def _stop(self, truth: RobotTruth) -> dict[str, NDArray[np.float64]]:
        """A stop's arrays, (1, ...) each (made once per stop: a plan's stops repeat)."""
        known = self._stops.get(id(truth))
        if known is None or known[0] is not truth:
            known = self._stops[id(truth)] = (truth, _nominal(truth, 1))
        return known[1]

    def moved(
        self, points: NDArray[np.float64], rows: NDArray[np.intp] | slice
    ) -> NDArray[np.float64]:
        """(R, ..., 3) points of the trials' nominal stops (W) moved with their true poses.
        The robot's turn is about the vertical through its origin."""
        true, pose = self.true[rows], self.nominal["pose"][rows]
        r = rot_z(true[:, 2] - pose[:, 2])
        flat = points.reshape(len(true), -1, 3).copy()
        flat[..., :2] -= pose[:, None, :2]
        out = np.einsum("tij,tkj->tki", r, flat)
        out[..., :2] += true[:, None, :2]
        return out.reshape(points.shape)


def _nominal(truth: RobotTruth, trials: int) -> dict[str, NDArray[np.float64]]:
    """A robot's stop as arrays, each repeated for ``trials`` trials."""
    out = {"pose": truth.pose}
    if truth.cubes is not None and truth.leds is not None:
        out["cubes"], out["leds"] = truth.cubes, truth.leds
    if truth.instrument is not None and truth.instrument2world is not None:
        out["instrument"], out["orientation"] = truth.instrument, truth.instrument2world
        out["tilt"] = np.array(tilt_from_orientation(truth.instrument2world))
    return {k: np.repeat(np.asarray(v, dtype=float)[None], trials, axis=0) for k, v in out.items()}


@dataclass
class BatchOutcome:
    """What T trials of a plan gave.

    Attributes:
        calibrations: (camera, visit) -> the visit's calibrations, with its errors (see
            :class:`VisitOutcome`).
        parent_error: (T, 3) the parent's final estimate minus its truth, m.
        parent_covariance: (T, 3, 3) its predicted covariance, m^2.
        distance: (T,) the parent's travel by its own estimates, m.
        failures: (T,) consistency tests failed (the geometric fidelity would measure again).
    """

    calibrations: dict[tuple[str, int], VisitOutcome]
    parent_error: NDArray[np.float64]
    parent_covariance: NDArray[np.float64]
    distance: NDArray[np.float64]
    failures: NDArray[np.int64]


@dataclass
class VisitOutcome:
    """A visit's calibration in T trials: (T,) arrays unless said.

    Attributes:
        points: LED points used (fewer where a trial gave up stops). distance: the
            parent's travel at the calibration, m.
        position_error: m. rotation_error: rad (NaN where not calibrated).
        position_offset: (T, 3) calibrated minus true camera centre in W, m (NaN where not
            calibrated).
        world_pixel, world_3d: Table III against the reference set (px, m), NaN without one.
        local_pixel, local_3d: Table III against the visit's own data (px, m).
        predicted_transfer, predicted_calibration: the analytic prediction's RMS 3D
            position error from the parent's pose and from the calibration itself, m.
        calibrated: whether each trial's calibration succeeded.
    """

    points: NDArray[np.int64]
    distance: NDArray[np.float64]
    position_error: NDArray[np.float64]
    rotation_error: NDArray[np.float64]
    position_offset: NDArray[np.float64]
    world_pixel: NDArray[np.float64]
    world_3d: NDArray[np.float64]
    local_pixel: NDArray[np.float64]
    local_3d: NDArray[np.float64]
    predicted_transfer: NDArray[np.float64]
    predicted_calibration: NDArray[np.float64]
    calibrated: NDArray[np.bool_]


@dataclass
class _DataSet:
    """A data set's stops in the trials that took it (``rows``; ``alive``: those that have
    not started again since), in order: each stop's k <= N_led LED points."""

    rows: NDArray[np.intp]
    alive: NDArray[np.bool_]
    points: list[NDArray[np.float64]] = field(default_factory=list)  # (R, k, 3) each
    pixels: list[NDArray[np.float64]] = field(default_factory=list)  # (R, k, 2) each
    covariances: list[NDArray[np.float64]] = field(default_factory=list)  # (R, 3N_led, 3N_led)
    leds: list[NDArray[np.intp]] = field(default_factory=list)  # (k,) each: which LEDs
    children: list[str] = field(default_factory=list)  # each stop's child
    surveys: list[NDArray[np.float64]] = field(default_factory=list)  # (R, 3N_led, M) each
    size: int | None = None

    def arrays(self, n: int | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(R, n, 3) points and (R, n, 2) pixels, the first n LED points in order."""
        if not self.points:
            return np.zeros((0, 0, 3)), np.zeros((0, 0, 2))
        pts = np.concatenate(self.points, axis=1)
        pix = np.concatenate(self.pixels, axis=1)
        n = pts.shape[1] if n is None else n
        return pts[:, :n], pix[:, :n]

    def stops(self) -> NDArray[np.float64]:
        """(R, S, 3N_led, 3N_led) the covariance of each stop's LEDs, all N_led of them
        (the joint covariance of the data set is block-diagonal: one block a stop)."""
        return np.stack(self.covariances, axis=1)

    def shared(self) -> NDArray[np.float64] | None:
        """(R, S 3N_led, C M) the stops' loadings on their children's surveying errors in
        the layout of :meth:`stops` (None where the assembly is known exactly)."""
        if not self.covariances:
            return None
        return survey_layout(self.children, self.surveys, self.covariances[0].shape[-1])

    def slots(self) -> NDArray[np.intp]:
        """(n,) where each LED point sits in the layout of :meth:`stops` (S stops of N_led
        LEDs): ``s N_led + led``; ``arange(n)`` when every stop holds every LED."""
        if not self.leds:
            return np.zeros(0, dtype=np.intp)
        n_led = self.covariances[0].shape[-1] // 3
        return np.concatenate([s * n_led + leds for s, leds in enumerate(self.leds)])


Rows = NDArray[np.intp] | slice
"""Which trials a step runs for: all of them (``slice(None)``) or an index array."""

ALL: slice = slice(None)


def _take(value: Any, rows: NDArray[np.intp]) -> Any:
    """A dataclass of (T, ...) arrays (or an array) for the trials ``rows`` only."""
    if isinstance(value, np.ndarray):
        return value[rows]
    return replace(value, **{f.name: getattr(value, f.name)[rows] for f in fields(value)})


def _put(old: Any, rows: NDArray[np.intp], new: Any, trials: int) -> Any:
    """``old`` (a dataclass of (T, ...) arrays, an array, or None: blank) with the trials
    ``rows`` taken from ``new``; a new object, ``old`` is left as it was."""
    if isinstance(new, np.ndarray):
        out = _blank(new, trials) if old is None else np.array(old, copy=True)
        out[rows] = new
        return out
    return replace(
        new,
        **{
            f.name: _put(
                None if old is None else getattr(old, f.name), rows, getattr(new, f.name), trials
            )
            for f in fields(new)
        },
    )


def _blank_rows(value: Any, n: int) -> Any:
    """A dataclass of arrays like ``value`` for ``n`` trials that have filled nothing."""
    return replace(value, **{f.name: _blank(getattr(value, f.name), n) for f in fields(value)})


def _blank(like: NDArray[Any], trials: int) -> NDArray[Any]:
    """(T, ...) an array like ``like``'s rows that no trial has filled: NaN, 0 or False."""
    fill: Any = np.nan if np.issubdtype(like.dtype, np.floating) else 0
    return np.full((trials, *like.shape[1:]), fill, dtype=like.dtype)


class BatchRun:
    """T trials of a plan, executed step by step (:meth:`step`, or :meth:`run` for all).

    The trials may also go their own ways: :meth:`step` with ``rows`` runs a step for some
    trials only, :meth:`drive_rows` drives a robot of each of them to its own stop, and
    :meth:`restart` starts some trials again with new seeds; each trial then gives what
    it would give alone with the steps it took (the environment's vector runs its
    episodes so, each its own campaign, as the rows of one batch). The global adjustment's
    records (``record_network``) need every trial to take every step.

    Args:
        plan: the campaign's plan.
        seeds: (T,) each trial's root seed.
        noise: the noise the trials simulate (an error budget's one source: see
            :func:`twin.montecarlo.sources.isolate`); default the plan's scenario's.
        led_px: each camera's simulated LED pixel noise by name, px (its detector's and its
            centroid error: :meth:`twin.scenario.Scenario.projected_led_px`); default the
            plan's cameras with ``noise``.
        estimators: the estimators (default: :class:`twin.batch.vectorised.Vectorised`,
            the campaign's own as array code).
        record_network: keep what each trial measured for its global adjustment
            (:attr:`network`, :mod:`twin.batch.network`).

    Attributes:
        executed: the steps executed so far (a restart counts one).
        last_estimate: each trial's parent estimate at its last fix. last_truth: (T, 3)
            the instrument's true centre there, m.
    """

    def __init__(
        self,
        plan: BatchPlan,
        seeds: Sequence[int],
        noise: Noise | None = None,
        estimators: Estimators | None = None,
        led_px: Mapping[str, float] | None = None,
        record_network: bool = False,
    ) -> None:
        self.network = NetworkRecorder() if record_network else None
        if estimators is None:
            estimators = Vectorised()
        sc = plan.scenario
        self.plan = plan
        self.trials = len(seeds)
        self.noise = noise if noise is not None else sc.noise
        self.spec: TotalStationSpec = self.noise.total_station.spec()
        self.inclinometer: InclinometerSpec = self.noise.inclinometer.spec()
        # The instrument advertises the scenario's full noise: the estimators weigh by it.
        self.advertised: TotalStationSpec = sc.noise.total_station.spec()
        self.advertised_tilt: InclinometerSpec = sc.noise.inclinometer.spec()
        self.advertised_led_px = {c.name: sc.projected_led_px(c.name) for c in sc.cameras}
        if led_px is None:
            simulated = sc.model_copy(update={"noise": self.noise})
            led_px = {c.name: simulated.projected_led_px(c.name) for c in sc.cameras}
        self.led_px = dict(led_px)
        self.estimators = estimators
        self.marker: MarkerAssembly = sc.marker.assembly()
        self.n_leds = len(self.marker.leds_body)
        self.seeds = list(seeds)
        self.draws = Draws(seeds, draws_needed(plan, self.n_leds))
        self._creep_draws: Draws | None = None
        t = self.trials
        self._leg_started = np.zeros(t, dtype=bool)
        self.robots = {name: _Robot.at(truth, t) for name, truth in plan.start.items()}
        self.built: dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]] = {}
        self._build(ALL)
        solver = "wls" if len(plan.children) > 1 else "closed_form"
        self.cps: CpsStates = estimators.cps(
            t, plan.children, solver, FALSE_ALARM_RATE, sc.campaign.child_creep_m
        )
        self.placed: dict[str, tuple[Observations, ParentEstimates]] = {}
        self.datasets: dict[tuple[str, str, int], list[_DataSet]] = {}
        self.tracks: list[list[NDArray[np.float64]]] = [[] for _ in range(t)]
        self.distance = np.zeros(t)
        self.failures = np.zeros(t, dtype=np.int64)
        self.visits: dict[tuple[str, int], VisitOutcome] = {}
        self.executed = 0
        self.last_estimate: ParentEstimates | None = None
        self.last_truth = np.zeros((t, 3))
        self._record_fix(self.cps.parent, self._start_centre(t), ALL)

    def _build(self, rows: Rows) -> None:
        """The trials' marker assemblies, each child's as built (its surveying error)."""
        sigma = self.noise.marker_geometry_m
        picked = None if isinstance(rows, slice) else rows
        for child in self.plan.children:
            cubes = sigma * self.draws.take(3, 3, rows=picked)
            leds = sigma * self.draws.take(self.n_leds, 3, rows=picked)
            if child not in self.built:
                self.built[child] = (cubes, leds)
            else:
                self.built[child][0][rows], self.built[child][1][rows] = cubes, leds

    def _start_centre(self, n: int) -> NDArray[np.float64]:
        instrument = self.plan.start[self.plan.parent].instrument
        assert instrument is not None
        return np.repeat(instrument[None], n, axis=0)

    # -- the steps -------------------------------------------------------------------------
    def run(self) -> BatchOutcome:
        """Execute every step of the plan and return the outcome."""
        for step in self.plan.steps:
            self.step(step)
        return self.outcome()

    def step(self, step: object, rows: ArrayLike | None = None) -> None:
        """Execute one step of the plan for every trial, or for the trials ``rows``."""
        r = self._rows(rows)
        self.executed += 1
        if isinstance(step, Drive):
            self._drive([step], r)
        elif isinstance(step, Place):
            self._place(step.child, r)
        elif isinstance(step, Fix):
            self._fix(step.children, r)
        elif isinstance(step, Point):
            self._point(step, r)
        elif isinstance(step, DataSetDone):
            self._dataset(
                (step.dataset, step.camera, step.visit), r, open_only=True
            ).size = step.points
        elif isinstance(step, Calibrate):
            self._calibrate(step, r)
        else:
            raise TypeError(f"unknown step {step!r}")

    def drive_rows(self, steps: Sequence[Drive], rows: ArrayLike) -> None:
        """Drive one robot in each of the trials ``rows`` (R,) to its own stop
        (``steps[i]`` for ``rows[i]``)."""
        r = self._rows(rows)
        assert not isinstance(r, slice)
        if len(steps) != len(r) or len({s.robot for s in steps}) != 1:
            raise ValueError("drive_rows needs one drive of one robot per row")
        self.executed += 1
        self._drive(steps, r)

    def _rows(self, rows: ArrayLike | None) -> Rows:
        if rows is None:
            return ALL
        if self.network is not None:
            raise ValueError("a batch that records the network runs every step for every trial")
        r = np.asarray(rows, dtype=np.intp).reshape(-1)
        if len(r) and (r.min() < 0 or r.max() >= self.trials or len(np.unique(r)) < len(r)):
            raise ValueError(f"rows must be distinct trials of 0 .. {self.trials - 1}")
        return r

    def _picked(self, r: Rows) -> NDArray[np.intp] | None:
        """The draws' rows: None for every trial."""
        return None if isinstance(r, slice) else r

    def _count(self, r: Rows) -> int:
        return self.trials if isinstance(r, slice) else len(r)

    def _drive(self, steps: Sequence[Drive], r: Rows) -> None:
        step = steps[0]
        robot = self.robots[step.robot]
        if len(steps) == 1:
            believed = np.repeat(step.believed[None], self._count(r), axis=0)
        else:
            believed = np.stack([s.believed for s in steps])
        offset = _compose(robot.true[r], _inverse(robot.believed[r]))
        true = _compose(offset, believed)
        stop = self.noise.stopping
        true[:, :2] += stop.sigma_xy * self.draws.take(2, rows=self._picked(r))
        true[:, 2] += stop.sigma_yaw * self.draws.take(1, rows=self._picked(r))[:, 0]
        robot.true[r], robot.believed[r] = true, believed
        robot.stopped([s.truth for s in steps], r)
        creep = self.noise.child_creep_m
        if step.robot == self.plan.parent and creep > 0:
            # The standing children creep once per leg of the parent (twin.sim.rig.creep),
            # from their own stream: switching creep on changes no other draw.
            index = np.arange(self.trials)[r]
            fresh = index[~self._leg_started[index]]
            if len(fresh):
                self._leg_started[fresh] = True
                if self._creep_draws is None:
                    self._creep_draws = Draws(self.seeds, 0, stream=CREEP_BATCH_STREAM)
                picked = None if len(fresh) == self.trials else fresh
                for child in self.plan.children:
                    self.robots[child].true[fresh, :2] += creep * self._creep_draws.take(
                        2, rows=picked
                    )

    # -- shots -----------------------------------------------------------------------------
    def _instrument(self, r: Rows) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The instrument's true centre (R, 3), m, and orientation (R, 3, 3) in W."""
        parent = self.robots[self.plan.parent]
        nominal = parent.nominal
        centre = parent.moved(nominal["instrument"][r][:, None, :], r)[:, 0]
        turn = rot_z(parent.true[r, 2] - nominal["pose"][r, 2])
        return centre, turn @ nominal["orientation"][r]

    def _cubes(self, child: str, r: Rows) -> NDArray[np.float64]:
        """(R, 3, 3) the child's true cubes in W, its assembly's surveying error included."""
        robot = self.robots[child]
        error = np.einsum("tij,tkj->tki", rot_z(robot.true[r, 2]), self.built[child][0][r])
        return robot.moved(robot.nominal["cubes"][r], r) + error

    def _leds(self, child: str, r: Rows) -> NDArray[np.float64]:
        """(R, N_led, 3) the child's true LEDs in W."""
        robot = self.robots[child]
        error = np.einsum("tij,tkj->tki", rot_z(robot.true[r, 2]), self.built[child][1][r])
        return robot.moved(robot.nominal["leds"][r], r) + error

    def _shots(self, child: str, r: Rows) -> NDArray[np.float64]:
        """(R, 3, 3) levelled, rounded polar shots at the child's three cubes."""
        centre, orientation = self._instrument(r)
        # In the instrument's (tilted) frame: R^T (p - c).
        local = np.einsum("tji,tkj->tki", orientation, self._cubes(child, r) - centre[:, None])
        # The instrument's tilt is the nominal station's (a turn about z leaves it).
        tilt = self.robots[self.plan.parent].nominal["tilt"][r]
        polar = cartesian2polar(local)
        picked = self._picked(r)
        noisy = normalise_polar(
            polar + polar_sigmas(polar, self.spec) * self.draws.take(3, 3, rows=picked)
        )
        reading = self.inclinometer.sigma * self.draws.take(3, 2, rows=picked)
        levelled = level_points(
            polar2cartesian(noisy), tilt[:, :1] + reading[..., 0], tilt[:, 1:] + reading[..., 1]
        )
        return quantise_polar(cartesian2polar(levelled), self.spec)

    def _observe(self, child: str, r: Rows) -> Observations:
        obs = self.estimators.observe(
            self._shots(child, r),
            self.advertised,
            self.advertised_tilt,
            self.marker,
            FALSE_ALARM_RATE,
        )
        self.failures[r] += obs.inconsistent
        return obs

    # -- CPS -------------------------------------------------------------------------------
    def _cps(self, r: Rows) -> CpsStates:
        """The CPS states of the trials ``r`` (write them back with :meth:`_cps_done`)."""
        return self.cps if isinstance(r, slice) else self.cps.on_rows(r)

    def _cps_done(self, r: Rows, part: CpsStates) -> None:
        if not isinstance(r, slice):
            self.cps.put_rows(r, part)

    def _place(self, child: str, r: Rows) -> None:
        obs = self._observe(child, r)
        cps = self._cps(r)
        cps.children_moved(child, obs)
        self._cps_done(r, cps)
        if self.network is not None:
            self.network.stand(child, obs.point, obs.covariance, cps.child_position(child))
        parent = cps.parent
        # The child's localisation is corrected from its marker's pose (as the campaign does).
        rotation = parent.rotation @ obs.rotation
        origin = parent.level2world(obs.translation[:, None, :])[:, 0]
        self.robots[child].believed[r] = np.column_stack(
            [origin[:, 0], origin[:, 1], np.arctan2(rotation[:, 1, 0], rotation[:, 0, 0])]
        )
        if isinstance(r, slice):
            self.placed[child] = (obs, parent)
        else:
            before = self.placed.get(child, (None, None))
            self.placed[child] = (
                _put(before[0], r, obs, self.trials),
                _put(before[1], r, parent, self.trials),
            )

    def _fix(self, children: tuple[str, ...], r: Rows) -> None:
        self._leg_started[r] = False  # the parent's next drive starts a leg
        observations = [(child, self._observe(child, r)) for child in children]
        cps = self._cps(r)
        self.failures[r] += cps.parent_moved(observations)
        self._cps_done(r, cps)
        parent = cps.parent
        self.robots[self.plan.parent].believed[r] = np.column_stack(
            [parent.translation[:, 0], parent.translation[:, 1], parent.yaw]
        )
        centre, _ = self._instrument(r)
        self._record_fix(parent, centre, r)
        if self.network is not None:
            for child, obs in observations:
                self.network.sight(child, obs.point, obs.covariance)

    def _record_fix(
        self, parent: ParentEstimates, true_centre: NDArray[np.float64], r: Rows
    ) -> None:
        """The trials ``r`` fixed the parent at ``parent`` (R rows); its instrument truly
        stood at ``true_centre`` (R, 3)."""
        if self.last_estimate is not None:
            last = self.last_estimate.translation[r][:, :2]
            distance = self.distance.copy()
            distance[r] += np.linalg.norm(parent.translation[:, :2] - last, axis=1)
            self.distance = distance
        if isinstance(r, slice):
            self.last_estimate, self.last_truth = parent, np.asarray(true_centre, dtype=float)
        else:
            self.last_estimate = _put(self.last_estimate, r, parent, self.trials)
            self.last_truth = _put(
                self.last_truth, r, np.asarray(true_centre, dtype=float), self.trials
            )
        index = np.arange(self.trials)[r]
        for i, k in enumerate(index):
            self.tracks[k].append(parent.translation[i])
        if self.network is not None:
            self.network.station(parent.yaw, parent.translation)

    def track(self, row: int) -> list[NDArray[np.float64]]:
        """(3,) the parent's estimated instrument centre at each of its fixes in trial
        ``row`` (since its last restart), m (W)."""
        return list(self.tracks[row])

    # -- data and calibrations -------------------------------------------------------------
    def _dataset(self, key: tuple[str, str, int], r: Rows, open_only: bool = False) -> _DataSet:
        """The data set ``key`` (dataset, camera, visit) of the trials ``r``: the latest
        they took together (``open_only``: still being taken), or a new one."""
        index = np.arange(self.trials)[r]
        cohorts = self.datasets.setdefault(key, [])
        for data in reversed(cohorts):
            if (
                np.array_equal(data.rows, index)
                and data.alive.all()
                and not (open_only and data.size is not None)
            ):
                return data
        data = _DataSet(index, np.ones(len(index), dtype=bool))
        cohorts.append(data)
        return data

    def _point(self, step: Point, r: Rows) -> None:
        obs, parent = self.placed[step.child]
        if not isinstance(r, slice):
            obs, parent = _take(obs, r), _take(parent, r)
        n = self._count(r)
        leds_level, cov_level = self.estimators.leds(obs, self.marker)
        world = parent.level2world(leds_level)
        # The levelled frame turns about z into W: each LED's 3 x 3 block turns with it.
        turn = np.kron(np.eye(leds_level.shape[1]), parent.rotation)
        camera = self.plan.cameras[step.camera]
        true = self._leds(step.child, r)
        pixels = camera.project_or_nan(true.reshape(-1, 3)).reshape(n, -1, 2)
        # An LED is found when all of its blob lies in the image (as the camera's sensor
        # has it).
        distance = np.linalg.norm(true - camera.position, axis=2)
        margin = camera.f * self.plan.led_radii[step.child] / distance
        seen = in_image(pixels.reshape(-1, 2), camera.image_size, margin.reshape(-1))
        seen = seen.reshape(n, -1)
        pixels = pixels + self.led_px[step.camera] * self.draws.take(
            true.shape[1], 2, rows=self._picked(r)
        )
        leds = np.asarray(step.leds, dtype=np.intp)
        if len(leds) < true.shape[1]:
            # The LEDs the plan's camera found at this stop; the others give no point.
            world, pixels, seen = world[:, leds], pixels[:, leds], seen[:, leds]
        missed = _missed(seen, step.partial)
        self.failures[r] += missed.any(axis=1)
        world = np.where(missed[..., None], np.nan, world)
        pixels = np.where(missed[..., None], np.nan, pixels)
        data = self._dataset((step.dataset, step.camera, step.visit), r, open_only=True)
        data.points.append(world)
        data.pixels.append(pixels)
        data.covariances.append(turn @ cov_level @ np.swapaxes(turn, 1, 2))
        # The assembly's surveying error, turned with the child (the same at every stop).
        data.children.append(step.child)
        data.surveys.append(
            survey_loading(self.marker, rot_z(self.robots[step.child].true[r, 2]))
            if self.marker.survey_sigma > 0
            else np.zeros((0, 0))
        )
        if self.network is not None and step.dataset == "visit":
            rows = (3 * leds[:, None] + np.arange(3)).ravel()  # the planned LEDs' blocks
            cov = data.covariances[-1][:, rows][:, :, rows]
            survey = data.surveys[-1]
            self.network.stop(
                step.camera,
                step.visit,
                world,
                cov,
                pixels,
                step.child,
                survey[:, rows] if survey.size else None,
            )
        data.leds.append(leds)

    def _reference(
        self, camera: str, r: Rows
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """(R, n, 3) points and (R, n, 2) pixels of the camera's reference data set of each
        of the trials ``r`` (the latest each took), or None where one has none."""
        index = np.arange(self.trials)[r]
        points: list[NDArray[np.float64]] = []
        pixels: list[NDArray[np.float64]] = []
        for k in index:
            for data in reversed(self.datasets.get(("reference", camera, 0), [])):
                where = np.flatnonzero((data.rows == k) & data.alive)
                if len(where) and data.points:
                    pts, pix = data.arrays(data.size)
                    points.append(pts[where[0]])
                    pixels.append(pix[where[0]])
                    break
            else:
                return None
        if len({p.shape for p in points}) > 1:
            return None
        return np.stack(points), np.stack(pixels)

    def _calibrate(self, step: Calibrate, r: Rows) -> None:
        data = self._dataset(("visit", step.camera, step.visit), r)
        n = self._count(r)
        points, pixels = data.arrays(step.points)
        # A trial that gave up too many stops is not calibrated (the campaign's rule).
        too_few = found(points, pixels).sum(axis=1) < self.plan.scenario.campaign.min_points
        pixels = np.where(too_few[:, None, None], np.nan, pixels)
        truth = self.plan.cameras[step.camera]
        est = self.estimators
        cal = est.calibrate(points, pixels, truth.image_size, step.nominal)
        if self.network is not None:
            self.network.calibrated(
                step.camera, step.visit, cal.cameras, cal.calibrated, step.points
            )
        position_error, rotation_error = est.truth_errors(cal, truth)
        local = est.evaluate(cal, points, pixels)
        reference = self._reference(step.camera, r)
        if reference is not None:
            world = est.evaluate(cal, *reference)
        else:
            world = (np.full(n, np.nan), np.full(n, np.nan))
        assert self.last_estimate is not None
        parent = self.last_estimate if isinstance(r, slice) else _take(self.last_estimate, r)
        own = own_position_variance(
            cal.position_std,
            cal.sigma_px,
            self.advertised_led_px[step.camera],
            np.trace(
                est.points_effect(
                    cal, points, data.stops(), data.slots()[: points.shape[1]], data.shared()
                ),
                axis1=1,
                axis2=2,
            ),
        )
        outcome = VisitOutcome(
            points=np.isfinite(pixels).all(axis=2).sum(axis=1),
            distance=self.distance[r].copy(),
            position_error=position_error,
            rotation_error=rotation_error,
            position_offset=np.where(
                cal.calibrated[:, None], cal.position - truth.position, np.nan
            ),
            world_pixel=world[0],
            world_3d=world[1],
            local_pixel=local[0],
            local_3d=local[1],
            predicted_transfer=transfer_rms(parent, cal.position),
            predicted_calibration=np.sqrt(own),
            calibrated=cal.calibrated,
        )
        key = (step.camera, step.visit)
        if isinstance(r, slice):
            self.visits[key] = outcome
        else:
            self.visits[key] = _put(self.visits.get(key), r, outcome, self.trials)

    # -- trials that start again -----------------------------------------------------------
    def restart(self, rows: ArrayLike, seeds: Sequence[int]) -> None:
        """Start the trials ``rows`` (R,) again, each from its new seed: as new trials of
        the plan, before its first step (the others go on as they were)."""
        r = self._rows(rows)
        assert not isinstance(r, slice)
        if len(seeds) != len(r):
            raise ValueError(f"{len(seeds)} seeds for {len(r)} rows")
        self.executed += 1
        for k, seed in zip(r, seeds, strict=True):
            self.seeds[k] = int(seed)
        self.draws.restart(r, seeds)
        if self._creep_draws is not None:
            self._creep_draws.restart(r, seeds)
        for name, truth in self.plan.start.items():
            robot = self.robots[name]
            robot.true[r] = truth.pose
            robot.believed[r] = truth.pose
            robot.stopped([truth], r)
        self._build(r)
        self.cps.reset_rows(r)
        for key, cohorts in self.datasets.items():
            for data in cohorts:
                data.alive &= ~np.isin(data.rows, r)
            self.datasets[key] = [data for data in cohorts if data.alive.any()]
        for key, outcome in self.visits.items():
            self.visits[key] = _put(outcome, r, _blank_rows(outcome, len(r)), self.trials)
        self._leg_started[r] = False
        self.distance = self.distance.copy()
        self.distance[r] = 0.0
        self.failures[r] = 0
        # Their first fix: the parent's start, no travel yet.
        parent = _take(self.cps.parent, r)
        self.last_estimate = _put(self.last_estimate, r, parent, self.trials)
        self.last_truth = _put(self.last_truth, r, self._start_centre(len(r)), self.trials)
        for i, k in enumerate(r):
            self.tracks[k] = [parent.translation[i]]

    def outcome(self) -> BatchOutcome:
        """What the trials gave so far."""
        assert self.last_estimate is not None
        parent, truth = self.last_estimate, self.last_truth
        return BatchOutcome(
            calibrations=dict(self.visits),
            parent_error=parent.translation - truth,
            parent_covariance=parent.covariance[:, 1:, 1:],
            distance=self.distance.copy(),
            failures=self.failures.copy(),
        )


def _missed(seen: NDArray[np.bool_], partial: bool) -> NDArray[np.bool_]:
    """(T, k) which of a stop's k planned LEDs each trial gives up, from (T, k) which it
    found: where the stop's plan is ``partial`` only the LEDs it missed (as the campaign
    does), else a trial that misses one gives up the whole stop. Either counts one failure
    a stop."""
    if partial:
        return ~seen
    lost = ~seen.all(axis=1)
    return np.broadcast_to(lost[:, None], seen.shape)


def transfer_rms(parent: ParentEstimates, camera: NDArray[np.float64]) -> NDArray[np.float64]:
    """(T,) RMS 3D error of a camera's centre (T, 3) from the parent's pose error at the
    station (:func:`twin.montecarlo.prediction.camera_position_covariance`), m."""
    lever = camera - parent.translation
    jac = np.zeros((len(lever), 3, 4))
    jac[:, 0, 0], jac[:, 1, 0] = -lever[:, 1], lever[:, 0]
    jac[:, :, 1:] = np.eye(3)
    cov = jac @ parent.covariance @ np.swapaxes(jac, 1, 2)
    return np.sqrt(np.trace(cov, axis1=1, axis2=2))
