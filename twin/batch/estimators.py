"""The campaign's estimators over the trials of a batch: what the campaign computes from one
trial's measurements, for T trials.

:class:`Estimators` is what the batch executor (:mod:`twin.batch.execute`) needs of them:

- :meth:`Estimators.observe`: a child's reference point, its covariance and its marker's
  pose from three levelled cube shots (:func:`twin.localization.observation.observe_child`);
- :meth:`Estimators.cps`: the group's CPS state (:class:`twin.localization.sequence.
  CpsSequence`): children placed, the parent's pose solved;
- :meth:`Estimators.leds`: a stop's LED positions from its marker's pose
  (:func:`twin.instruments.marker_pose.led_positions`);
- :meth:`Estimators.calibrate`, :meth:`Estimators.evaluate`: Tsai's calibration of a visit
  and the Table III metrics (:func:`calib.tsai.calibrate_tsai`, :func:`calib.evaluate`).

:class:`TrialByTrial` runs the scalar code of the campaign on each trial in turn: slow, and
the reference the vectorised estimators are held to.
"""

from __future__ import annotations

import abc
import copy
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from calib import calibrate_tsai, evaluate
from calib.camera import TsaiCamera, TsaiCameras
from calib.metrics import pose_errors
from calib.point_errors import covariance_from_point_errors
from calib.rotation import rot_z
from twin.instruments.consistency import chi2_threshold
from twin.instruments.marker import MarkerAssembly
from twin.instruments.marker_pose import MARKER_DOF, MarkerPose, cube_centroid, fit_marker_pose
from twin.instruments.marker_pose import led_positions as scalar_led_positions
from twin.instruments.noise import cartesian_covariance
from twin.instruments.polar import polar2cartesian
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec
from twin.localization.input_checks_batch import block_diagonal
from twin.localization.observation import ChildObservation
from twin.localization.sequence import CpsSequence


@dataclass(frozen=True)
class Observations:
    """A child measured in T trials (the parent's levelled frame).

    Attributes:
        point: (T, 3) reference points, m. covariance: (T, 3, 3), m^2.
        rotation: (T, 3, 3) marker body to levelled frame. translation: (T, 3), m.
        pose_covariance: (T, 6, 6) of the marker pose (d_theta rad, d_t m).
        inconsistent: (T,) whether the three shots failed the marker's consistency test.
    """

    point: NDArray[np.float64]
    covariance: NDArray[np.float64]
    rotation: NDArray[np.float64]
    translation: NDArray[np.float64]
    pose_covariance: NDArray[np.float64]
    inconsistent: NDArray[np.bool_]


@dataclass(frozen=True)
class ParentEstimates:
    """The parent's CPS estimate in T trials: yaw (T,) rad, translation (T, 3) m,
    covariance (T, 4, 4) of (yaw, x, y, z)."""

    yaw: NDArray[np.float64]
    translation: NDArray[np.float64]
    covariance: NDArray[np.float64]

    @property
    def rotation(self) -> NDArray[np.float64]:
        """(T, 3, 3) levelled frame to W."""
        return rot_z(self.yaw)

    def level2world(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """(T, ..., 3) points of the levelled frame -> W, m."""
        r = self.rotation
        shape = points.shape
        flat = points.reshape(len(self.yaw), -1, 3)
        return (np.einsum("tij,tkj->tki", r, flat) + self.translation[:, None, :]).reshape(shape)


class CpsStates(abc.ABC):
    """The CPS state of T trials."""

    @abc.abstractmethod
    def children_moved(self, child: str, observations: Observations) -> None:
        """A child moved; the standing parent measured it (place it in W)."""

    @abc.abstractmethod
    def parent_moved(self, observations: Sequence[tuple[str, Observations]]) -> NDArray[np.bool_]:
        """The parent moved and measured these children; solve its pose. Returns (T,) which
        trials failed the consistency test (their solution is kept)."""

    @property
    @abc.abstractmethod
    def parent(self) -> ParentEstimates:
        """The parent's current estimate."""

    @abc.abstractmethod
    def child_position(self, child: str) -> NDArray[np.float64]:
        """(T, 3) a child's reference point in W, m."""

    @abc.abstractmethod
    def on_rows(self, rows: NDArray[np.intp]) -> CpsStates:
        """The states of the trials ``rows`` (R,): its steps change these states only once
        :meth:`put_rows` writes them back."""

    @abc.abstractmethod
    def put_rows(self, rows: NDArray[np.intp], part: CpsStates) -> None:
        """Take the trials ``rows`` from ``part`` (:meth:`on_rows` of the same rows)."""

    @abc.abstractmethod
    def reset_rows(self, rows: NDArray[np.intp]) -> None:
        """Start the trials ``rows`` again: the parent at W's origin, no child placed."""


@dataclass(frozen=True)
class Calibrations:
    """A camera calibrated in T trials.

    Attributes:
        cameras: the T calibrated cameras (a trial whose calibration failed holds the
            start camera: see ``calibrated``).
        position: (T, 3) optical centres in W, m (NaN where failed).
        position_std: (T, 3) their standard deviations from Tsai's covariance, m (the
            fit's residual standard deviation times the unit covariance).
        sigma_px: (T,) the fit's residual standard deviation, px.
        calibrated: (T,) whether each trial's calibration succeeded.
        kept: (T, N) which points each trial measured (:func:`found`).
    """

    cameras: TsaiCameras
    position: NDArray[np.float64]
    position_std: NDArray[np.float64]
    sigma_px: NDArray[np.float64]
    calibrated: NDArray[np.bool_]
    kept: NDArray[np.bool_]


def found(points: NDArray[np.float64], pixels: NDArray[np.float64]) -> NDArray[np.bool_]:
    """(..., N) which of (..., N, 3) points and (..., N, 2) pixels a trial measured (the
    rest are NaN: stops it gave up)."""
    return np.isfinite(points).all(axis=-1) & np.isfinite(pixels).all(axis=-1)


def by_count(kept: NDArray[np.bool_]) -> Iterator[tuple[NDArray[np.intp], NDArray[np.intp]]]:
    """The trials of a (T, N) mask grouped by how many points they kept.

    Yields:
        ``(trials, rows)``: (G,) trial indices and (G, n) the indices of their n kept
        points, in order (``points[trials[:, None], rows]`` is their (G, n, 3) data).
    """
    counts = kept.sum(axis=1)
    for n in np.unique(counts):
        trials = np.flatnonzero(counts == n)
        yield trials, np.nonzero(kept[trials])[1].reshape(len(trials), int(n))


def coordinate_rows(rows: NDArray[np.intp]) -> NDArray[np.intp]:
    """(G, n) point indices -> (G, 3n) their x, y, z rows of a (3N, 3N) covariance."""
    return (3 * rows[..., None] + np.arange(3)).reshape(len(rows), -1)


def slot_rows(rows: NDArray[np.intp], slots: NDArray[np.intp] | None) -> NDArray[np.intp]:
    """(G, n) point indices -> (G, 3n) their x, y, z rows of a block-diagonal covariance
    whose layout places point j at ``slots[j]`` (in order where ``slots`` is None)."""
    return coordinate_rows(rows if slots is None else np.asarray(slots)[rows])


class Estimators(abc.ABC):
    """What the batch executor needs to estimate, for T trials at once (see the module)."""

    @abc.abstractmethod
    def observe(
        self,
        polar: NDArray[np.float64],
        spec: TotalStationSpec,
        inclinometer: InclinometerSpec | None,
        marker: MarkerAssembly,
        false_alarm_rate: float | None,
    ) -> Observations:
        """A child's observations from (T, 3, 3) levelled polar shots at its three cubes."""

    @abc.abstractmethod
    def cps(
        self,
        trials: int,
        children: Sequence[str],
        solver: str,
        false_alarm_rate: float | None,
        child_creep: float = 0.0,
    ) -> CpsStates:
        """A new CPS state for ``trials`` trials (the parent at W's origin); ``child_creep``
        as :class:`twin.localization.sequence.CpsSequence`'s, m."""

    @abc.abstractmethod
    def leds(
        self, observations: Observations, marker: MarkerAssembly
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(T, N_led, 3) LED positions in the levelled frame and their (T, 3N, 3N)
        covariance from the marker's pose."""

    @abc.abstractmethod
    def calibrate(
        self,
        points: NDArray[np.float64],
        pixels: NDArray[np.float64],
        image_size: tuple[int, int],
        start: TsaiCamera,
    ) -> Calibrations:
        """Tsai's calibration of (T, N, 3) points and (T, N, 2) pixels (NaN rows are
        points a trial did not measure: :func:`found`)."""

    @abc.abstractmethod
    def evaluate(
        self,
        calibrations: Calibrations,
        points: NDArray[np.float64],
        pixels: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(T,) mean pixel error, px, and (T,) mean 3D error, m, of each trial's camera on
        its (T, M, 3) points and (T, M, 2) pixels (NaN where not calibrated)."""

    @abc.abstractmethod
    def points_effect(
        self,
        calibrations: Calibrations,
        points: NDArray[np.float64],
        stops: NDArray[np.float64],
        slots: NDArray[np.intp] | None = None,
        shared: NDArray[np.float64] | None = None,
    ) -> NDArray[np.float64]:
        """(T, 3, 3) covariance of each calibrated camera's centre, m^2, from the errors of
        its (T, n, 3) points (NaN where not calibrated), to first order at the calibrated
        camera (:func:`calib.point_errors.covariance_from_point_errors`).

        The points' joint covariance is block-diagonal, one (T, S, k, k) block a stop (its
        LEDs share the marker's measured pose), in a layout of S k / 3 points: ``slots``
        (n,) says where each point sits in it (default: the first n, in order; a stop that
        shows only some LEDs leaves the others' rows out of the data); plus ``S S^T`` for
        the (T, S k, M) ``shared`` loadings of the layout on errors common to its stops (a
        child's marker survey: :func:`twin.instruments.marker_pose.survey_layout`)."""

    def truth_errors(
        self, calibrations: Calibrations, truth: TsaiCamera
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(T,) position error, m, and (T,) rotation error, rad, against the true camera
        (NaN where not calibrated)."""
        errors = pose_errors(calibrations.cameras, truth)
        failed = ~calibrations.calibrated
        return (
            np.where(failed, np.nan, errors.position_m),
            np.where(failed, np.nan, errors.rotation_rad),
        )


def calibrate_one(
    points: NDArray[np.float64], pixels: NDArray[np.float64], image_size: tuple[int, int]
) -> tuple[TsaiCamera, NDArray[np.float64], NDArray[np.float64], float] | None:
    """One trial's calibration as the campaign makes it (:func:`calib.calibrate_tsai`):
    the camera, its (3,) centre and standard deviations, m, and the residual sigma, px; None
    where it fails."""
    try:
        result = calibrate_tsai(points, pixels, image_size)
    except ValueError:
        return None
    cam = result.camera
    assert isinstance(cam, TsaiCamera)
    s = result.std_by_name
    return cam, cam.position, np.array([s["x"], s["y"], s["z"]]), result.sigma_px


# -- the reference: the campaign's scalar code, trial by trial -------------------------------------
class _ScalarCps(CpsStates):
    def __init__(
        self,
        trials: int,
        children: Sequence[str],
        solver: str,
        rate: float | None,
        creep: float = 0.0,
    ):
        self.rate, self.creep = rate, creep
        # The consistency test is made here, not by the sequence: a trial that fails it
        # keeps its solution (the campaign would measure again; the batch counts it).
        self.sequences = [
            CpsSequence(list(children), solver=solver, false_alarm_rate=None, child_creep=creep)
            for _ in range(trials)
        ]

    def children_moved(self, child: str, observations: Observations) -> None:
        for k, seq in enumerate(self.sequences):
            seq.children_moved([_observation(child, observations, k)])

    def parent_moved(self, observations: Sequence[tuple[str, Observations]]) -> NDArray[np.bool_]:
        flags = np.zeros(len(self.sequences), dtype=bool)
        for k, seq in enumerate(self.sequences):
            step = seq.parent_moved([_observation(child, o, k) for child, o in observations])
            solution = step.solution
            if self.rate is not None and solution is not None and solution.chi2 is not None:
                flags[k] = solution.chi2 > chi2_threshold(solution.dof, self.rate)
        return flags

    @property
    def parent(self) -> ParentEstimates:
        poses = [s.parent for s in self.sequences]
        return ParentEstimates(
            np.array([p.yaw for p in poses]),
            np.array([p.translation for p in poses]),
            np.array([p.covariance for p in poses]),
        )

    def child_position(self, child: str) -> NDArray[np.float64]:
        return np.array([s.child_position(child)[0] for s in self.sequences])

    def on_rows(self, rows: NDArray[np.intp]) -> CpsStates:
        part = copy.copy(self)
        part.sequences = [self.sequences[k] for k in rows]  # stepped in place
        return part

    def put_rows(self, rows: NDArray[np.intp], part: CpsStates) -> None:
        pass  # the sequences of ``part`` are this batch's own

    def reset_rows(self, rows: NDArray[np.intp]) -> None:
        first = self.sequences[0]
        for k in rows:
            self.sequences[k] = CpsSequence(
                list(first.children),
                solver=first.solver,
                false_alarm_rate=None,
                child_creep=self.creep,
            )


def _observation(child: str, o: Observations, k: int) -> ChildObservation:
    return ChildObservation(child, o.point[k], o.covariance[k])


class TrialByTrial(Estimators):
    """The campaign's own scalar estimators, run on each trial in turn (the reference)."""

    def observe(self, polar, spec, inclinometer, marker, false_alarm_rate) -> Observations:
        cubes = polar2cartesian(polar)
        cov = cartesian_covariance(polar, spec, inclinometer)
        limit = np.inf if false_alarm_rate is None else chi2_threshold(MARKER_DOF, false_alarm_rate)
        out = {k: [] for k in ("point", "covariance", "rotation", "translation", "pose", "bad")}
        for k in range(len(polar)):
            pose = fit_marker_pose(cubes[k], marker, cov[k])
            point, point_cov = cube_centroid(cubes[k], cov[k])
            out["point"].append(point)
            out["covariance"].append(point_cov)
            out["rotation"].append(pose.rotation)
            out["translation"].append(pose.translation)
            out["pose"].append(pose.covariance)
            out["bad"].append(bool(pose.chi2 is not None and pose.chi2 > limit))
        return Observations(
            np.array(out["point"]),
            np.array(out["covariance"]),
            np.array(out["rotation"]),
            np.array(out["translation"]),
            np.array(out["pose"]),
            np.array(out["bad"]),
        )

    def cps(self, trials, children, solver, false_alarm_rate, child_creep=0.0) -> CpsStates:
        return _ScalarCps(trials, children, solver, false_alarm_rate, child_creep)

    def leds(self, observations, marker):
        leds, covs = [], []
        for k in range(len(observations.point)):
            pose = MarkerPose(
                observations.rotation[k],
                observations.translation[k],
                observations.pose_covariance[k],
                0.0,
            )
            led, cov = scalar_led_positions(pose, marker)
            leds.append(led)
            covs.append(cov)
        return np.array(leds), np.array(covs)

    def calibrate(self, points, pixels, image_size, start) -> Calibrations:
        kept = found(points, pixels)
        cameras: list[TsaiCamera] = []
        position = np.full((len(points), 3), np.nan)
        std = np.full((len(points), 3), np.nan)
        sigma = np.full(len(points), np.nan)
        for k in range(len(points)):
            one = calibrate_one(points[k][kept[k]], pixels[k][kept[k]], image_size)
            if one is None:
                cameras.append(start)
                continue
            cam, position[k], std[k], sigma[k] = one
            cameras.append(cam)
        made = np.isfinite(position).all(axis=1)
        return Calibrations(TsaiCameras.from_cameras(cameras), position, std, sigma, made, kept)

    def evaluate(self, calibrations, points, pixels):
        pix = np.full(len(points), np.nan)
        err = np.full(len(points), np.nan)
        kept = found(points, pixels)
        for k in np.flatnonzero(calibrations.calibrated & kept.any(axis=1)):
            m = evaluate(calibrations.cameras.camera(k), points[k][kept[k]], pixels[k][kept[k]])
            pix[k], err[k] = m.pixel.mean, m.error_3d.mean
        return pix, err

    def points_effect(self, calibrations, points, stops, slots=None, shared=None):
        out = np.full((len(points), 3, 3), np.nan)
        for k in np.flatnonzero(calibrations.calibrated):
            rows = np.flatnonzero(calibrations.kept[k])
            cols = slot_rows(rows[None], slots)[0]
            joint = block_diagonal(stops[k : k + 1])[0]
            if shared is not None:
                joint = joint + shared[k] @ shared[k].T
            cov = covariance_from_point_errors(
                calibrations.cameras.camera(k), points[k][rows], joint[np.ix_(cols, cols)]
            )
            out[k] = cov[8:11, 8:11]
        return out
