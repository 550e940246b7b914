"""A straight leapfrog CPS run (the paper's Fig. 6), simulated in pure numpy.

Truth, noisy measurements, the estimator and its predicted covariance in one place, shared
by the tests and ``benchmarks/bench_cps.py``. One CPS step k (k = 0 .. n_steps-1):

1. the two children move to their places around the parent's next station and stop;
2. the parent, still at station k, measures the three cubes of each child;
3. the parent moves ``step_length`` along the corridor (x) to station k+1;
4. it measures the stationary children again and solves its pose.

Each child is represented by the centroid of its three cubes (see
:mod:`twin.localization.observation`); the fit of its three cubes to the marker assembly is
kept as a chi-square (:func:`twin.instruments.marker_pose.marker_consistency_chi2`) and
tested by :func:`run_cps` as :func:`observe_child` tests a real observation. Every shot
goes through the instrument model of :func:`twin.instruments.shot.measure_points`: noise
in the tilted instrument frame, levelling with a noisy inclination reading, rounding to the
output resolution. The parent stops with a position and heading error and stands tilted
(within the compensator's range); the children stop with position and heading errors. The
world frame is the parent's levelled frame at station 0, whose pose is therefore exactly known.

Formations (positions relative to the parent's next station, x along the corridor):

- ``IN_LINE``: children ahead on the corridor's axis at ``near_gap`` and
  ``near_gap + child_spacing``, staggered by +/- ``stagger`` across so the near child's mast
  does not hide the far child's cubes;
- ``SIDE_BY_SIDE``: both at ``near_gap`` ahead, at +/- ``half_width`` across the corridor.

The data are clean (every prism locked right, no child moves), so every consistency error
in :func:`evaluate` is a false alarm; it counts them (``LeapfrogResult.rejected_runs``),
and they should number about ``false_alarm_rate`` times the number of tests.
"""

from __future__ import annotations

import enum
import math
import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from calib.rotation import rot_z, wrap_angle
from twin.instruments.consistency import (
    DEFAULT_FALSE_ALARM_RATE,
    check_false_alarm_rate,
    exceeds_threshold,
    raise_if_inconsistent,
)
from twin.instruments.errors import FailureReason, InconsistentMarkerError
from twin.instruments.marker import MarkerAssembly
from twin.instruments.marker_pose import MARKER_DOF, marker_consistency_chi2
from twin.instruments.noise import cartesian_covariance
from twin.instruments.polar import polar2cartesian
from twin.instruments.shot import measure_points
from twin.instruments.tilt import tilt_rotation
from twin.instruments.total_station import ARCSEC, InclinometerSpec, TotalStationSpec
from twin.localization.input_checks import DEFAULT_MIN_BASELINE, coincide_message
from twin.localization.joint_state import CpsBatch
from twin.localization.observation import (
    ChildObservation,
    ChildObservationBatch,
    reference_from_cubes,
)
from twin.localization.sequence import CpsSequence

CHILDREN = ("child1", "child2")
STEP_DURATION = 60.0
"""Nominal duration of one CPS step, s (only used for timestamps)."""


class Formation(enum.Enum):
    """Where the two children stand relative to the parent's next station."""

    IN_LINE = "in_line"
    SIDE_BY_SIDE = "side_by_side"


@dataclass(frozen=True)
class LeapfrogConfig:
    """Geometry and noise of a straight leapfrog run. Lengths in m, angles in rad.

    Attributes:
        formation: children in line ahead, or side by side across the corridor.
        route_length: distance the parent travels, m (the paper's 85 m).
        step_length: the parent's advance per CPS step, m.
        near_gap: distance along the corridor from the parent's next station to the nearer
            child, m.
        child_spacing: in line, distance between the two children along the corridor, m.
        stagger: in line, lateral offset (+/-) of the children, m.
        half_width: side by side, lateral offset (+/-) of each child, m.
        instrument_height: height of the instrument centre above the floor, m.
        stop_sigma: stopping error of every robot, each horizontal axis, m.
        heading_sigma: parent heading error at each station, rad.
        child_heading_sigma: child heading error, rad.
        max_tilt: the parent's true tilt is uniform in [-max_tilt, max_tilt] on each axis.
        spec, inclinometer, marker: instrument and marker models.
    """

    formation: Formation = Formation.IN_LINE
    route_length: float = 85.0
    step_length: float = 5.0
    near_gap: float = 3.0
    child_spacing: float = 5.0
    stagger: float = 0.25
    half_width: float = 1.0
    instrument_height: float = 0.75
    stop_sigma: float = 0.02
    heading_sigma: float = math.radians(1.0)
    child_heading_sigma: float = math.radians(5.0)
    max_tilt: float = 60.0 * ARCSEC
    spec: TotalStationSpec = field(default_factory=TotalStationSpec)
    inclinometer: InclinometerSpec = field(default_factory=InclinometerSpec)
    marker: MarkerAssembly = field(default_factory=MarkerAssembly)

    def __post_init__(self) -> None:
        if not isinstance(self.formation, Formation):
            raise ValueError(f"formation must be a Formation, got {self.formation!r}")
        for name in (
            "route_length",
            "step_length",
            "near_gap",
            "instrument_height",
            "child_spacing",
            "half_width",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"LeapfrogConfig.{name} must be positive, got {value}")
        for name in (
            "stagger",
            "stop_sigma",
            "heading_sigma",
            "child_heading_sigma",
            "max_tilt",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"LeapfrogConfig.{name} must be non-negative, got {value}")
        ratio = self.route_length / self.step_length
        if abs(ratio - round(ratio)) > 1e-9:
            raise ValueError(
                f"route_length ({self.route_length} m) must be a whole number of steps of "
                f"{self.step_length} m"
            )
        if self.max_tilt > self.inclinometer.working_range:
            raise ValueError(
                f"max_tilt {self.max_tilt / ARCSEC:.1f}\" exceeds the compensator's working "
                f'range {self.inclinometer.working_range / ARCSEC:.1f}"'
            )
        if self.near_gap < self.spec.range_min + 0.5:
            raise ValueError(
                f"near_gap {self.near_gap} m is too close to the minimum range "
                f"{self.spec.range_min} m of the instrument"
            )

    @property
    def n_steps(self) -> int:
        """Number of CPS steps."""
        return round(self.route_length / self.step_length)

    def child_offsets(self) -> NDArray[np.float64]:
        """(2, 2) nominal (along, across) offsets of the children from the next station, m."""
        if self.formation is Formation.IN_LINE:
            return np.array(
                [[self.near_gap, self.stagger], [self.near_gap + self.child_spacing, -self.stagger]]
            )
        return np.array([[self.near_gap, self.half_width], [self.near_gap, -self.half_width]])


@dataclass(frozen=True, eq=False)
class LeapfrogData:
    """Truth and measurements of a batch of runs (R runs, S steps, 2 children).

    Attributes:
        config: the configuration simulated.
        parent_truth: (R, S + 1, 4) true (yaw, x, y, z) of the parent's levelled frame at
            each station.
        children_truth: (R, S, 2, 3) true world reference points of the children at step k.
        before, before_cov: (R, S, 2, 3) children measured from station k (levelled frame)
            and (R, S, 2, 3, 3) their covariance.
        after, after_cov: the same measured from station k + 1.
        before_marker_chi2, after_marker_chi2: (R, S, 2) chi-square (3 dof) of each
            child's three measured cubes against the marker assembly.
    """

    config: LeapfrogConfig
    parent_truth: NDArray[np.float64]
    children_truth: NDArray[np.float64]
    before: NDArray[np.float64]
    before_cov: NDArray[np.float64]
    after: NDArray[np.float64]
    after_cov: NDArray[np.float64]
    before_marker_chi2: NDArray[np.float64] | None = None
    after_marker_chi2: NDArray[np.float64] | None = None

    @property
    def n_runs(self) -> int:
        """Number of runs R."""
        return self.parent_truth.shape[0]


def simulate_leapfrog(
    config: LeapfrogConfig, n_runs: int, rng: np.random.Generator
) -> LeapfrogData:
    """Simulate the truth and every measurement of ``n_runs`` independent runs."""
    if n_runs < 1:
        raise ValueError(f"n_runs must be at least 1, got {n_runs}")
    r, s = n_runs, config.n_steps
    stations = np.arange(s + 1) * config.step_length

    parent = np.zeros((r, s + 1, 4))
    parent[:, :, 1] = stations
    parent[:, 1:, 1:3] += config.stop_sigma * rng.standard_normal((r, s, 2))
    parent[:, 1:, 0] = config.heading_sigma * rng.standard_normal((r, s))
    tilt = rng.uniform(-config.max_tilt, config.max_tilt, size=(r, s + 1, 2))

    offsets = config.child_offsets()
    floor = np.zeros((r, s, 2, 3))
    floor[..., 0] = stations[1:, None] + offsets[None, :, 0]
    floor[..., 1] = offsets[None, :, 1]
    floor[..., :2] += config.stop_sigma * rng.standard_normal((r, s, 2, 2))
    floor[..., 2] = -config.instrument_height
    heading = config.child_heading_sigma * rng.standard_normal((r, s, 2))
    rot_child = rot_z(heading)  # (r, s, 2, 3, 3)
    cubes_w = (
        np.einsum("...ij,cj->...ci", rot_child, config.marker.cubes_body) + floor[..., None, :]
    )
    ref_w = np.einsum("...ij,j->...i", rot_child, config.marker.reference_body) + floor

    def measure(station: NDArray[np.int64]) -> tuple[NDArray, NDArray, NDArray]:
        pose = parent[:, station]  # (r, s, 4)
        rot_p = rot_z(pose[..., 0])[:, :, None, None]  # (r, s, 1, 1, 3, 3)
        level = np.einsum("...ji,...j->...i", rot_p, cubes_w - pose[:, :, None, None, 1:])
        t = tilt[:, station]
        to_level = tilt_rotation(t[..., 0], t[..., 1])[:, :, None, None]
        instrument = np.einsum("...ji,...j->...i", to_level, level)
        polar, _ = measure_points(
            instrument,
            t[:, :, None, None, 0],
            t[:, :, None, None, 1],
            config.spec,
            config.inclinometer,
            rng,
        )
        cubes = polar2cartesian(polar)
        point, cov = reference_from_cubes(cubes, polar, config.spec, config.inclinometer)
        cube_cov = cartesian_covariance(polar, config.spec, config.inclinometer)
        return point, cov, marker_consistency_chi2(cubes, cube_cov, config.marker)

    before, before_cov, before_chi2 = measure(np.arange(s))
    after, after_cov, after_chi2 = measure(np.arange(1, s + 1))
    return LeapfrogData(
        config, parent, ref_w, before, before_cov, after, after_cov, before_chi2, after_chi2
    )


def _check_markers(
    data: LeapfrogData, chi2: NDArray | None, run: int, k: int, rate: float | None
) -> None:
    if chi2 is None:
        return
    for i, name in enumerate(CHILDREN):
        raise_if_inconsistent(
            float(chi2[run, k, i]),
            MARKER_DOF,
            rate,
            InconsistentMarkerError,
            f"run {run}, step {k}, child {name!r}: the three cubes do not fit the marker",
            child=name,
        )


def run_cps(
    data: LeapfrogData,
    run: int,
    solver: str = "wls",
    false_alarm_rate: float | None = DEFAULT_FALSE_ALARM_RATE,
) -> CpsSequence:
    """Run the CPS estimator over one simulated run; returns the full sequence record.

    Raises:
        InconsistentMarkerError, InconsistentChildrenError: a consistency test failed at
            ``false_alarm_rate`` (None: no test), as in a campaign.
    """
    rate = check_false_alarm_rate(false_alarm_rate)
    seq = CpsSequence(CHILDREN, solver=solver, false_alarm_rate=rate)
    for k in range(data.config.n_steps):
        t0 = 2.0 * k * STEP_DURATION
        _check_markers(data, data.before_marker_chi2, run, k, rate)
        seq.children_moved(
            [
                ChildObservation(name, data.before[run, k, i], data.before_cov[run, k, i], t0)
                for i, name in enumerate(CHILDREN)
            ]
        )
        t1 = t0 + STEP_DURATION
        _check_markers(data, data.after_marker_chi2, run, k, rate)
        seq.parent_moved(
            [
                ChildObservation(name, data.after[run, k, i], data.after_cov[run, k, i], t1)
                for i, name in enumerate(CHILDREN)
            ]
        )
    return seq


@dataclass(frozen=True, eq=False)
class LeapfrogResult:
    """Final errors of the parent over a batch of runs, with the predicted covariance.

    R counts the runs that completed; runs stopped by a consistency error are listed in
    ``rejected_runs`` (on clean data, false alarms) and left out of the arrays.

    Attributes:
        solver: ``"closed_form"`` or ``"wls"``.
        position_error: (R, 3) estimated minus true final position, m.
        yaw_error: (R,) estimated minus true final yaw, rad.
        covariance: (R, 4, 4) predicted covariance of (yaw, x, y, z).
        seconds_per_step: wall time of all the runs over their number and the steps of one
            (children + parent update, every run solved at once), s.
        rejected_runs: indices of the runs stopped by a consistency error.
        rejected_reasons: the reason for each of ``rejected_runs``.
    """

    solver: str
    position_error: NDArray[np.float64]
    yaw_error: NDArray[np.float64]
    covariance: NDArray[np.float64]
    seconds_per_step: float
    rejected_runs: tuple[int, ...] = ()
    rejected_reasons: tuple[FailureReason, ...] = ()

    @property
    def position_nees(self) -> NDArray[np.float64]:
        """(R,) normalised estimation error squared of the final position (mean 3)."""
        e = self.position_error
        return np.einsum(
            "ri,ri->r", e, np.linalg.solve(self.covariance[:, 1:, 1:], e[..., None])[..., 0]
        )

    @property
    def yaw_nees(self) -> NDArray[np.float64]:
        """(R,) squared yaw error over its predicted variance (mean 1)."""
        return self.yaw_error**2 / self.covariance[:, 0, 0]

    @property
    def position_error_norm(self) -> NDArray[np.float64]:
        """(R,) Euclidean final position error, m."""
        return np.linalg.norm(self.position_error, axis=1)

    @property
    def predicted_position_rms(self) -> NDArray[np.float64]:
        """(R,) square root of the trace of the predicted position covariance, m."""
        return np.sqrt(np.trace(self.covariance[:, 1:, 1:], axis1=1, axis2=2))


def evaluate(
    data: LeapfrogData,
    solver: str,
    false_alarm_rate: float | None = DEFAULT_FALSE_ALARM_RATE,
) -> LeapfrogResult:
    """Run the estimator over every run of ``data`` at once and collect the final errors.

    All runs are solved together (:class:`CpsBatch`); a run counts as stopped at its first
    consistency error, where :func:`run_cps` would raise, in the same order of tests (the
    markers before each children step, the markers then the children at each parent
    step). It is counted in ``rejected_runs`` and left out.

    Raises:
        ValueError: a run that was not stopped lost its solution (the children coincide).
    """
    rate = check_false_alarm_rate(false_alarm_rate)
    r = data.n_runs
    reason: list[FailureReason | None] = [None] * r
    stopped = np.zeros(r, dtype=bool)

    def stop(flags: NDArray[np.bool_], why: FailureReason) -> None:
        for i in np.flatnonzero(flags & ~stopped):
            reason[i] = why
        stopped[:] |= flags

    def observe(points: NDArray, cov: NDArray, k: int, t: float) -> list[ChildObservationBatch]:
        return [
            ChildObservationBatch(name, points[:, k, i], cov[:, k, i], t)
            for i, name in enumerate(CHILDREN)
        ]

    start = time.perf_counter()
    batch = CpsBatch(CHILDREN, r, solver=solver, false_alarm_rate=rate)
    for k in range(data.config.n_steps):
        t0 = 2.0 * k * STEP_DURATION
        for i in range(len(CHILDREN)):
            stop(
                exceeds_threshold(data.before_marker_chi2[:, k, i], MARKER_DOF, rate),
                FailureReason.INCONSISTENT_MARKER,
            )
        batch.children_moved(observe(data.before, data.before_cov, k, t0))
        for i in range(len(CHILDREN)):
            stop(
                exceeds_threshold(data.after_marker_chi2[:, k, i], MARKER_DOF, rate),
                FailureReason.INCONSISTENT_MARKER,
            )
        solution = batch.parent_moved(observe(data.after, data.after_cov, k, t0 + STEP_DURATION))
        lost = solution.poor_geometry & ~stopped
        if lost.any():
            raise ValueError(
                f"run {int(np.flatnonzero(lost)[0])}, step {k}: "
                + coincide_message(solution.baseline[lost][0], DEFAULT_MIN_BASELINE)
            )
        stop(solution.inconsistent, FailureReason.INCONSISTENT_CHILDREN)
    elapsed = time.perf_counter() - start
    final = batch.parent
    truth = data.parent_truth[:, -1]
    done = ~stopped
    rejected = np.flatnonzero(stopped)
    return LeapfrogResult(
        solver,
        final.translation[done] - truth[done, 1:],
        wrap_angle(final.yaw[done] - truth[done, 0]),
        final.covariance[done],
        elapsed / (r * data.config.n_steps),
        tuple(int(i) for i in rejected),
        tuple(reason[i] for i in rejected),  # type: ignore[misc]
    )
