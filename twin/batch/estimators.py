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
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from calib import calibrate_tsai, evaluate
from calib.camera import TsaiCamera
from calib.rotation import rotation_angle_between
from twin.instruments.consistency import chi2_threshold
from twin.instruments.marker import MarkerAssembly
from twin.instruments.marker_pose import MARKER_DOF, MarkerPose, cube_centroid, fit_marker_pose
from twin.instruments.marker_pose import led_positions as scalar_led_positions
from twin.instruments.noise import cartesian_covariance
from twin.instruments.polar import polar2cartesian
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec
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
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        out = np.zeros((len(self.yaw), 3, 3))
        out[:, 0, 0], out[:, 0, 1], out[:, 1, 0], out[:, 1, 1] = c, -s, s, c
        out[:, 2, 2] = 1.0
        return out

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


@dataclass(frozen=True)
class Calibrations:
    """A camera calibrated in T trials.

    Attributes:
        cameras: the calibrated cameras (None where a trial's calibration failed).
        position: (T, 3) optical centres in W, m (NaN where failed).
        position_std: (T, 3) their standard deviations, m.
        calibrated: (T,) whether each trial's calibration succeeded.
    """

    cameras: tuple[TsaiCamera | None, ...]
    position: NDArray[np.float64]
    position_std: NDArray[np.float64]
    calibrated: NDArray[np.bool_]


def found(points: NDArray[np.float64], pixels: NDArray[np.float64]) -> NDArray[np.bool_]:
    """(N,) which of (N, 3) points and (N, 2) pixels a trial measured (the rest are NaN:
    stops it gave up)."""
    return np.isfinite(points).all(axis=1) & np.isfinite(pixels).all(axis=1)


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
        self, trials: int, children: Sequence[str], solver: str, false_alarm_rate: float | None
    ) -> CpsStates:
        """A new CPS state for ``trials`` trials (the parent at W's origin)."""

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

    def truth_errors(
        self, calibrations: Calibrations, truth: TsaiCamera
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(T,) position error, m, and (T,) rotation error, rad, against the true camera."""
        pos = np.linalg.norm(calibrations.position - truth.position, axis=1)
        rot = np.array(
            [
                np.nan if c is None else rotation_angle_between(c.world2cam_r, truth.world2cam_r)
                for c in calibrations.cameras
            ]
        )
        return pos, rot


# -- the reference: the campaign's scalar code, trial by trial -------------------------------------
class _ScalarCps(CpsStates):
    def __init__(self, trials: int, children: Sequence[str], solver: str, rate: float | None):
        self.rate = rate
        # The consistency test is made here, not by the sequence: a trial that fails it
        # keeps its solution (the campaign would measure again; the batch counts it).
        self.sequences = [
            CpsSequence(list(children), solver=solver, false_alarm_rate=None) for _ in range(trials)
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

    def cps(self, trials, children, solver, false_alarm_rate) -> CpsStates:
        return _ScalarCps(trials, children, solver, false_alarm_rate)

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
        cameras: list[TsaiCamera | None] = []
        position, std = [], []
        for k in range(len(points)):
            kept = found(points[k], pixels[k])
            try:
                result = calibrate_tsai(points[k][kept], pixels[k][kept], image_size)
            except ValueError:
                cameras.append(None)
                position.append(np.full(3, np.nan))
                std.append(np.full(3, np.nan))
                continue
            cam = result.camera
            assert isinstance(cam, TsaiCamera)
            cameras.append(cam)
            position.append(cam.position)
            s = result.std_by_name
            std.append(np.array([s["x"], s["y"], s["z"]]))
        return Calibrations(
            tuple(cameras),
            np.array(position),
            np.array(std),
            np.array([c is not None for c in cameras]),
        )

    def evaluate(self, calibrations, points, pixels):
        pix, err = [], []
        for k, cam in enumerate(calibrations.cameras):
            kept = found(points[k], pixels[k])
            if cam is None or not kept.any():
                pix.append(np.nan)
                err.append(np.nan)
                continue
            m = evaluate(cam, points[k][kept], pixels[k][kept])
            pix.append(m.pixel.mean)
            err.append(m.error_3d.mean)
        return np.array(pix), np.array(err)
