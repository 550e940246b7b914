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
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

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
    batch, the chunk or how far ahead the draws were reserved.

    Args:
        seeds: (T,) the trials' root seeds.
        count: draws each trial is expected to need (reserved at once; more are drawn as
            they are needed).
        stream: the spawn key of the trials' generators (a source with its own stream
            changes no other source's draws when it is switched on).
    """

    def __init__(self, seeds: Sequence[int], count: int, stream: int = BATCH_STREAM) -> None:
        self._generators = [
            np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(stream,)))
            for seed in seeds
        ]
        self.values = np.zeros((len(seeds), 0))
        self.used = 0
        self._reserve(count)

    def _reserve(self, count: int) -> None:
        more = np.stack([g.standard_normal(count) for g in self._generators])
        self.values = np.concatenate([self.values[:, self.used :], more], axis=1)
        self.used = 0

    def take(self, *shape: int) -> NDArray[np.float64]:
        """(T, *shape) the next draws of every trial."""
        n = math.prod(shape)
        if self.used + n > self.values.shape[1]:
            self._reserve(max(n, 4096))
        out = self.values[:, self.used : self.used + n].reshape(len(self.values), *shape)
        self.used += n
        return out


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
    (T, 3)), and where it stood in the noise-free plan."""

    true: NDArray[np.float64]
    believed: NDArray[np.float64]
    nominal: RobotTruth

    def moved(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """(..., 3) points of the nominal stop (W) moved with each trial's true pose:
        (T, ..., 3). The robot's turn is about the vertical through its origin."""
        delta = self.true[:, 2] - self.nominal.pose[2]
        r = rot_z(delta)
        rel = points - np.array([*self.nominal.pose[:2], 0.0])
        flat = rel.reshape(-1, 3)
        out = np.einsum("tij,kj->tki", r, flat).reshape(len(delta), *points.shape)
        out[..., 0] += self.true[:, 0].reshape((-1,) + (1,) * (points.ndim - 1))
        out[..., 1] += self.true[:, 1].reshape((-1,) + (1,) * (points.ndim - 1))
        return out


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
    """A data set's stops in T trials, in order: each stop's k <= N_led LED points."""

    points: list[NDArray[np.float64]] = field(default_factory=list)  # (T, k, 3) each
    pixels: list[NDArray[np.float64]] = field(default_factory=list)  # (T, k, 2) each
    covariances: list[NDArray[np.float64]] = field(default_factory=list)  # (T, 3N_led, 3N_led)
    leds: list[NDArray[np.intp]] = field(default_factory=list)  # (k,) each: which LEDs
    children: list[str] = field(default_factory=list)  # each stop's child
    surveys: list[NDArray[np.float64]] = field(default_factory=list)  # (T, 3N_led, M) each
    size: int | None = None

    def arrays(self, n: int | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(T, n, 3) points and (T, n, 2) pixels, the first n LED points in order."""
        if not self.points:
            return np.zeros((0, 0, 3)), np.zeros((0, 0, 2))
        pts = np.concatenate(self.points, axis=1)
        pix = np.concatenate(self.pixels, axis=1)
        n = pts.shape[1] if n is None else n
        return pts[:, :n], pix[:, :n]

    def stops(self) -> NDArray[np.float64]:
        """(T, S, 3N_led, 3N_led) the covariance of each stop's LEDs, all N_led of them
        (the joint covariance of the data set is block-diagonal: one block a stop)."""
        return np.stack(self.covariances, axis=1)

    def shared(self) -> NDArray[np.float64] | None:
        """(T, S 3N_led, C M) the stops' loadings on their children's surveying errors in
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


class BatchRun:
    """T trials of a plan, executed step by step (:meth:`step`, or :meth:`run` for all).

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
        executed: the steps executed so far.
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
        n_leds = len(self.marker.leds_body)
        self.seeds = list(seeds)
        self.draws = Draws(seeds, draws_needed(plan, n_leds))
        self._creep_draws: Draws | None = None
        self._leg_started = False
        t = self.trials
        self.robots = {
            name: _Robot(
                np.repeat(truth.pose[None], t, axis=0),
                np.repeat(truth.pose[None], t, axis=0),
                truth,
            )
            for name, truth in plan.start.items()
        }
        sigma = self.noise.marker_geometry_m
        self.built = {
            child: (
                sigma * self.draws.take(3, 3),
                sigma * self.draws.take(n_leds, 3),
            )
            for child in plan.children
        }
        solver = "wls" if len(plan.children) > 1 else "closed_form"
        self.cps: CpsStates = estimators.cps(
            t, plan.children, solver, FALSE_ALARM_RATE, sc.campaign.child_creep_m
        )
        self.placed: dict[str, tuple[Observations, ParentEstimates]] = {}
        self.datasets: dict[tuple[str, str, int], _DataSet] = {}
        self.fixes: list[tuple[ParentEstimates, NDArray[np.float64]]] = []
        self.distance = np.zeros(t)
        self.failures = np.zeros(t, dtype=np.int64)
        self.visits: dict[tuple[str, int], VisitOutcome] = {}
        self.executed = 0
        self._record_fix(self.robots[plan.parent].nominal.instrument)

    # -- the steps -------------------------------------------------------------------------
    def run(self) -> BatchOutcome:
        """Execute every step of the plan and return the outcome."""
        for step in self.plan.steps:
            self.step(step)
        return self.outcome()

    def step(self, step: object) -> None:
        """Execute one step of the plan for every trial."""
        self.executed += 1
        if isinstance(step, Drive):
            self._drive(step)
        elif isinstance(step, Place):
            self._place(step.child)
        elif isinstance(step, Fix):
            self._fix(step.children)
        elif isinstance(step, Point):
            self._point(step)
        elif isinstance(step, DataSetDone):
            self._dataset(step).size = step.points
        elif isinstance(step, Calibrate):
            self._calibrate(step)
        else:
            raise TypeError(f"unknown step {step!r}")

    def _drive(self, step: Drive) -> None:
        robot = self.robots[step.robot]
        believed = np.repeat(step.believed[None], self.trials, axis=0)
        offset = _compose(robot.true, _inverse(robot.believed))
        true = _compose(offset, believed)
        stop = self.noise.stopping
        true[:, :2] += stop.sigma_xy * self.draws.take(2)
        true[:, 2] += stop.sigma_yaw * self.draws.take(1)[:, 0]
        robot.true, robot.believed, robot.nominal = true, believed, step.truth
        creep = self.noise.child_creep_m
        if step.robot == self.plan.parent and creep > 0 and not self._leg_started:
            # The standing children creep once per leg of the parent (twin.sim.rig.creep),
            # from their own stream: switching creep on changes no other draw.
            self._leg_started = True
            if self._creep_draws is None:
                self._creep_draws = Draws(self.seeds, 0, stream=CREEP_BATCH_STREAM)
            for child in self.plan.children:
                self.robots[child].true[:, :2] += creep * self._creep_draws.take(2)

    # -- shots -----------------------------------------------------------------------------
    def _instrument(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The instrument's true centre (T, 3), m, and orientation (T, 3, 3) in W."""
        parent = self.robots[self.plan.parent]
        nominal = parent.nominal
        assert nominal.instrument is not None
        assert nominal.instrument2world is not None
        centre = parent.moved(nominal.instrument)
        turn = rot_z(parent.true[:, 2] - nominal.pose[2])
        return centre, turn @ nominal.instrument2world

    def _cubes(self, child: str) -> NDArray[np.float64]:
        """(T, 3, 3) the child's true cubes in W, its assembly's surveying error included."""
        robot = self.robots[child]
        assert robot.nominal.cubes is not None
        error = np.einsum("tij,tkj->tki", rot_z(robot.true[:, 2]), self.built[child][0])
        return robot.moved(robot.nominal.cubes) + error

    def _leds(self, child: str) -> NDArray[np.float64]:
        """(T, N_led, 3) the child's true LEDs in W."""
        robot = self.robots[child]
        assert robot.nominal.leds is not None
        error = np.einsum("tij,tkj->tki", rot_z(robot.true[:, 2]), self.built[child][1])
        return robot.moved(robot.nominal.leds) + error

    def _shots(self, child: str) -> NDArray[np.float64]:
        """(T, 3, 3) levelled, rounded polar shots at the child's three cubes."""
        centre, orientation = self._instrument()
        # In the instrument's (tilted) frame: R^T (p - c).
        local = np.einsum("tji,tkj->tki", orientation, self._cubes(child) - centre[:, None])
        # The instrument's tilt is the nominal station's (a turn about z leaves it).
        roll, pitch = tilt_from_orientation(self.robots[self.plan.parent].nominal.instrument2world)
        polar = cartesian2polar(local)
        noisy = normalise_polar(polar + polar_sigmas(polar, self.spec) * self.draws.take(3, 3))
        reading = self.inclinometer.sigma * self.draws.take(3, 2)
        levelled = level_points(
            polar2cartesian(noisy), roll + reading[..., 0], pitch + reading[..., 1]
        )
        return quantise_polar(cartesian2polar(levelled), self.spec)

    def _observe(self, child: str) -> Observations:
        obs = self.estimators.observe(
            self._shots(child), self.advertised, self.advertised_tilt, self.marker, FALSE_ALARM_RATE
        )
        self.failures += obs.inconsistent
        return obs

    # -- CPS -------------------------------------------------------------------------------
    def _place(self, child: str) -> None:
        obs = self._observe(child)
        self.cps.children_moved(child, obs)
        if self.network is not None:
            self.network.stand(child, obs.point, obs.covariance, self.cps.child_position(child))
        parent = self.cps.parent
        # The child's localisation is corrected from its marker's pose (as the campaign does).
        r = parent.rotation @ obs.rotation
        origin = parent.level2world(obs.translation[:, None, :])[:, 0]
        self.robots[child].believed = np.column_stack(
            [origin[:, 0], origin[:, 1], np.arctan2(r[:, 1, 0], r[:, 0, 0])]
        )
        self.placed[child] = (obs, parent)

    def _fix(self, children: tuple[str, ...]) -> None:
        self._leg_started = False  # the parent's next drive starts a leg
        observations = [(child, self._observe(child)) for child in children]
        self.failures += self.cps.parent_moved(observations)
        parent = self.cps.parent
        self.robots[self.plan.parent].believed = np.column_stack(
            [parent.translation[:, 0], parent.translation[:, 1], parent.yaw]
        )
        centre, _ = self._instrument()
        self._record_fix(centre)
        if self.network is not None:
            for child, obs in observations:
                self.network.sight(child, obs.point, obs.covariance)

    def _record_fix(self, true_centre: NDArray[np.float64] | None) -> None:
        parent = self.cps.parent
        if self.fixes:
            last = self.fixes[-1][0].translation[:, :2]
            self.distance = self.distance + np.linalg.norm(parent.translation[:, :2] - last, axis=1)
        truth = np.zeros((self.trials, 3)) if true_centre is None else true_centre
        self.fixes.append((parent, np.broadcast_to(truth, (self.trials, 3))))
        if self.network is not None:
            self.network.station(parent.yaw, parent.translation)

    # -- data and calibrations -------------------------------------------------------------
    def _dataset(self, step: Point | DataSetDone | Calibrate, name: str | None = None) -> _DataSet:
        key = (name or getattr(step, "dataset", "visit"), step.camera, step.visit)
        return self.datasets.setdefault(key, _DataSet())

    def _point(self, step: Point) -> None:
        obs, parent = self.placed[step.child]
        leds_level, cov_level = self.estimators.leds(obs, self.marker)
        world = parent.level2world(leds_level)
        # The levelled frame turns about z into W: each LED's 3 x 3 block turns with it.
        turn = np.kron(np.eye(leds_level.shape[1]), parent.rotation)
        camera = self.plan.cameras[step.camera]
        true = self._leds(step.child)
        pixels = camera.project_or_nan(true.reshape(-1, 3)).reshape(self.trials, -1, 2)
        # An LED is found when all of its blob lies in the image (as the camera's sensor
        # has it).
        distance = np.linalg.norm(true - camera.position, axis=2)
        margin = camera.f * self.plan.led_radii[step.child] / distance
        seen = in_image(pixels.reshape(-1, 2), camera.image_size, margin.reshape(-1))
        seen = seen.reshape(self.trials, -1)
        pixels = pixels + self.led_px[step.camera] * self.draws.take(true.shape[1], 2)
        leds = np.asarray(step.leds, dtype=np.intp)
        if len(leds) < true.shape[1]:
            # The LEDs the plan's camera found at this stop; the others give no point.
            world, pixels, seen = world[:, leds], pixels[:, leds], seen[:, leds]
        missed = _missed(seen, step.partial)
        self.failures += missed.any(axis=1)
        world = np.where(missed[..., None], np.nan, world)
        pixels = np.where(missed[..., None], np.nan, pixels)
        data = self._dataset(step)
        data.points.append(world)
        data.pixels.append(pixels)
        data.covariances.append(turn @ cov_level @ np.swapaxes(turn, 1, 2))
        # The assembly's surveying error, turned with the child (the same at every stop).
        data.children.append(step.child)
        data.surveys.append(
            survey_loading(self.marker, rot_z(self.robots[step.child].true[:, 2]))
            if self.marker.survey_sigma > 0
            else np.zeros((0, 0))
        )
        if self.network is not None and getattr(step, "dataset", "visit") == "visit":
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

    def _calibrate(self, step: Calibrate) -> None:
        data = self._dataset(step, "visit")
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
        reference = self.datasets.get(("reference", step.camera, 0))
        if reference is not None and reference.points:
            world = est.evaluate(cal, *reference.arrays(reference.size))
        else:
            world = (np.full(self.trials, np.nan), np.full(self.trials, np.nan))
        parent = self.fixes[-1][0]
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
        self.visits[(step.camera, step.visit)] = VisitOutcome(
            points=np.isfinite(pixels).all(axis=2).sum(axis=1),
            distance=self.distance.copy(),
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

    def outcome(self) -> BatchOutcome:
        """What the trials gave so far."""
        parent, truth = self.fixes[-1]
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
