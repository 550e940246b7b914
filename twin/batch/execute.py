"""The batch fidelity: a campaign's plan (:mod:`twin.batch.steps`) executed for T trials at
once, every measurement and every estimate an array over the trials.

Each trial has its own noise, drawn from its own seed in a fixed order (so that a trial
gives the same result alone or in any batch), and the noise sources of the geometric
fidelity:

- the robots' stopping error and the children's creep, the marker assemblies' surveying
  error, the total station's noise and its inclination readings (:mod:`twin.batch.fleet`);
- the LED detection noise of the geometric fidelity (``noise.led_detection_px``) and the
  real camera's centroid error (``noise.led_centroid_px``).

The estimators are the campaign's, as array code (:mod:`twin.batch.estimators`): marker
fits and centroids, CPS with its joint covariance and consistency tests
(:class:`twin.localization.joint_state.CpsBatch`), LED positions from the marker's pose,
Tsai's calibration of every visit and the Table III metrics.

A data point holds the LEDs the camera found in the noise-free plan (:class:`twin.batch.
steps.Point`: all of them, or at stops chosen for accuracy those the stop shows);
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

import warnings
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.covariance import own_position_variance
from calib.rotation import rot_z
from twin.batch.datasets import DataSet, missed
from twin.batch.estimators import (
    Observations,
    ParentEstimates,
    calibrate,
    evaluate,
    found,
    leds,
    observe,
    points_effect,
    truth_errors,
)
from twin.batch.fleet import Fleet
from twin.batch.network import NetworkRecorder
from twin.batch.outcome import BatchOutcome, VisitOutcome, transfer_rms
from twin.batch.row_arrays import ALL, Rows, blank_rows, picked, put, take
from twin.batch.steps import BatchPlan, Calibrate, DataSetDone, Drive, Fix, Place, Point
from twin.batch.streams import Draws, draws_needed
from twin.instruments.marker import MarkerAssembly
from twin.instruments.marker_pose import survey_loading
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec
from twin.localization.input_checks import ConvergenceWarning
from twin.localization.joint_state import CpsBatch
from twin.localization.observation import ChildObservationBatch
from twin.scenario.schema import Noise
from twin.sim.capture import in_image

__all__ = ["BatchOutcome", "BatchRun", "VisitOutcome", "transfer_rms"]

FALSE_ALARM_RATE = 1e-4
"""The consistency tests' false-alarm rate, as the campaign's with a noisy instrument."""


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
        led_px: Mapping[str, float] | None = None,
        record_network: bool = False,
    ) -> None:
        self.network = NetworkRecorder() if record_network else None
        sc = plan.scenario
        self.plan = plan
        self.trials = len(seeds)
        self.noise = noise if noise is not None else sc.noise
        # The instrument advertises the scenario's full noise: the estimators weigh by it.
        self.advertised: TotalStationSpec = sc.noise.total_station.spec()
        self.advertised_tilt: InclinometerSpec = sc.noise.inclinometer.spec()
        self.advertised_led_px = {c.name: sc.projected_led_px(c.name) for c in sc.cameras}
        if led_px is None:
            simulated = sc.model_copy(update={"noise": self.noise})
            led_px = {c.name: simulated.projected_led_px(c.name) for c in sc.cameras}
        self.led_px = dict(led_px)
        self.marker: MarkerAssembly = sc.marker.assembly()
        self.n_leds = len(self.marker.leds_body)
        self.seeds = list(seeds)
        self.draws = Draws(seeds, draws_needed(plan, self.n_leds))
        self.fleet = Fleet(plan, self.noise, self.draws, self.seeds)
        self.robots = self.fleet.robots
        t = self.trials
        solver = "wls" if len(plan.children) > 1 else "closed_form"
        self.cps = CpsBatch(
            list(plan.children),
            t,
            solver=solver,
            false_alarm_rate=FALSE_ALARM_RATE,
            child_creep=sc.campaign.child_creep_m,
        )
        self.placed: dict[str, tuple[Observations, ParentEstimates]] = {}
        self.datasets: dict[tuple[str, str, int], list[DataSet]] = {}
        self.tracks: list[list[NDArray[np.float64]]] = [[] for _ in range(t)]
        self.distance = np.zeros(t)
        self.failures = np.zeros(t, dtype=np.int64)
        self.visits: dict[tuple[str, int], VisitOutcome] = {}
        self.executed = 0
        self.last_estimate: ParentEstimates | None = None
        self.last_truth = np.zeros((t, 3))
        self._record_fix(self._parent(self.cps), self.fleet.start_centre(t), ALL)

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
            self.fleet.drive([step], r)
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
        self.fleet.drive(steps, r)

    def _rows(self, rows: ArrayLike | None) -> Rows:
        if rows is None:
            return ALL
        if self.network is not None:
            raise ValueError("a batch that records the network runs every step for every trial")
        r = np.asarray(rows, dtype=np.intp).reshape(-1)
        if len(r) and (r.min() < 0 or r.max() >= self.trials or len(np.unique(r)) < len(r)):
            raise ValueError(f"rows must be distinct trials of 0 .. {self.trials - 1}")
        return r

    def _count(self, r: Rows) -> int:
        return self.trials if isinstance(r, slice) else len(r)

    # -- CPS -------------------------------------------------------------------------------
    def _observe(self, child: str, r: Rows) -> Observations:
        obs = observe(
            self.fleet.shots(child, r),
            self.advertised,
            self.advertised_tilt,
            self.marker,
            FALSE_ALARM_RATE,
        )
        self.failures[r] += obs.inconsistent
        return obs

    def _cps(self, r: Rows) -> CpsBatch:
        """The CPS states of the trials ``r`` (write them back with :meth:`_cps_done`)."""
        return self.cps if isinstance(r, slice) else self.cps.trials(r)

    def _cps_done(self, r: Rows, part: CpsBatch) -> None:
        if not isinstance(r, slice):
            self.cps.set_trials(r, part)

    @staticmethod
    def _parent(cps: CpsBatch) -> ParentEstimates:
        pose = cps.parent
        return ParentEstimates(pose.yaw, pose.translation, pose.covariance)

    def _place(self, child: str, r: Rows) -> None:
        obs = self._observe(child, r)
        cps = self._cps(r)
        cps.children_moved([ChildObservationBatch(child, obs.point, obs.covariance)])
        self._cps_done(r, cps)
        if self.network is not None:
            self.network.stand(child, obs.point, obs.covariance, cps.child_position(child)[0])
        parent = self._parent(cps)
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
                put(before[0], r, obs, self.trials),
                put(before[1], r, parent, self.trials),
            )

    def _fix(self, children: tuple[str, ...], r: Rows) -> None:
        self.fleet.leg_started[r] = False  # the parent's next drive starts a leg
        observations = [(child, self._observe(child, r)) for child in children]
        cps = self._cps(r)
        with warnings.catch_warnings():
            # A few trials of thousands whose Gauss-Newton stops at its iteration limit
            # keep that estimate, as the campaign's CPS does; a warning a chunk says nothing
            # the trials' errors do not.
            warnings.simplefilter("ignore", ConvergenceWarning)
            solution = cps.parent_moved(
                [ChildObservationBatch(c, o.point, o.covariance) for c, o in observations]
            )
        # A trial without a solution (children too close) is lost: its state is NaN and it
        # counts a failure at every later fix.
        self.failures[r] += solution.inconsistent | solution.poor_geometry
        self._cps_done(r, cps)
        parent = self._parent(cps)
        self.robots[self.plan.parent].believed[r] = np.column_stack(
            [parent.translation[:, 0], parent.translation[:, 1], parent.yaw]
        )
        centre, _ = self.fleet.instrument(r)
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
            self.last_estimate = put(self.last_estimate, r, parent, self.trials)
            self.last_truth = put(
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
    def _dataset(self, key: tuple[str, str, int], r: Rows, open_only: bool = False) -> DataSet:
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
        data = DataSet(index, np.ones(len(index), dtype=bool))
        cohorts.append(data)
        return data

    def _point(self, step: Point, r: Rows) -> None:
        obs, parent = self.placed[step.child]
        if not isinstance(r, slice):
            obs, parent = take(obs, r), take(parent, r)
        n = self._count(r)
        leds_level, cov_level = leds(obs, self.marker)
        world = parent.level2world(leds_level)
        # The levelled frame turns about z into W: each LED's 3 x 3 block turns with it.
        turn = np.kron(np.eye(leds_level.shape[1]), parent.rotation)
        camera = self.plan.cameras[step.camera]
        true = self.fleet.leds(step.child, r)
        pixels = camera.project_or_nan(true.reshape(-1, 3)).reshape(n, -1, 2)
        # An LED is found when all of its blob lies in the image (as the camera's sensor
        # has it).
        distance = np.linalg.norm(true - camera.position, axis=2)
        margin = camera.f * self.plan.led_radii[step.child] / distance
        seen = in_image(pixels.reshape(-1, 2), camera.image_size, margin.reshape(-1))
        seen = seen.reshape(n, -1)
        pixels = pixels + self.led_px[step.camera] * self.draws.take(
            true.shape[1], 2, rows=picked(r)
        )
        planned = np.asarray(step.leds, dtype=np.intp)
        if len(planned) < true.shape[1]:
            # The LEDs the plan's camera found at this stop; the others give no point.
            world, pixels, seen = world[:, planned], pixels[:, planned], seen[:, planned]
        lost = missed(seen, step.partial)
        self.failures[r] += lost.any(axis=1)
        world = np.where(lost[..., None], np.nan, world)
        pixels = np.where(lost[..., None], np.nan, pixels)
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
            rows = (3 * planned[:, None] + np.arange(3)).ravel()  # the planned LEDs' blocks
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
        data.leds.append(planned)

    def _reference(
        self, camera: str, r: Rows
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """(R, n, 3) points and (R, n, 2) pixels of the camera's reference data set of each
        of the trials ``r`` (the latest each took), or None where one has none."""
        index = np.arange(self.trials)[r]
        points: list[NDArray[np.float64]] = []
        pixels: list[NDArray[np.float64]] = []
        taken = self.datasets.get(("reference", camera, 0), [])
        arrays = [data.arrays(data.size) if data.points else None for data in taken]
        for k in index:
            for data, both in zip(reversed(taken), reversed(arrays), strict=True):
                where = np.flatnonzero((data.rows == k) & data.alive)
                if len(where) and both is not None:
                    pts, pix = both
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
        cal = calibrate(points, pixels, truth.image_size, step.nominal)
        if self.network is not None:
            self.network.calibrated(
                step.camera, step.visit, cal.cameras, cal.calibrated, step.points
            )
        position_error, rotation_error = truth_errors(cal, truth)
        local = evaluate(cal, points, pixels)
        reference = self._reference(step.camera, r)
        if reference is not None:
            world = evaluate(cal, *reference)
        else:
            world = (np.full(n, np.nan), np.full(n, np.nan))
        assert self.last_estimate is not None
        parent = self.last_estimate if isinstance(r, slice) else take(self.last_estimate, r)
        own = own_position_variance(
            cal.position_std,
            cal.sigma_px,
            self.advertised_led_px[step.camera],
            np.trace(
                points_effect(
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
            self.visits[key] = put(self.visits.get(key), r, outcome, self.trials)

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
        self.fleet.restart(r, seeds)
        self.cps.reset_trials(r)
        for key, cohorts in self.datasets.items():
            for data in cohorts:
                data.alive &= ~np.isin(data.rows, r)
            self.datasets[key] = [data for data in cohorts if data.alive.any()]
        for key, outcome in self.visits.items():
            self.visits[key] = put(outcome, r, blank_rows(outcome, len(r)), self.trials)
        self.distance = self.distance.copy()
        self.distance[r] = 0.0
        self.failures[r] = 0
        # Their first fix: the parent's start, no travel yet.
        parent = take(self._parent(self.cps), r)
        self.last_estimate = put(self.last_estimate, r, parent, self.trials)
        self.last_truth = put(self.last_truth, r, self.fleet.start_centre(len(r)), self.trials)
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
