"""The campaign's estimators as array code over the trials of a batch.

:class:`Vectorised` computes what :class:`twin.batch.estimators.TrialByTrial` computes with
the batched forms of the campaign's own estimators: the marker fit and the child's
observation (:func:`twin.localization.observation_batch.observe_child_batch`), the CPS state
(:class:`twin.localization.sequence_batch.CpsBatch`), the LED positions
(:func:`twin.instruments.marker_pose.led_positions_batch`), Tsai's calibration
(:func:`calib.tsai_lm.calibrate_tsai_batch`, from the visit's noise-free calibration)
and the Table III metrics (:mod:`calib.metrics`). The positioning numbers are the
scalar code's bit for bit, the calibrations its own to a small fraction of their standard
deviations (the tests hold them to it); no trial's numbers depend on the other trials of
its batch.

Trials that gave up stops calibrate on fewer points: trials are fitted in groups of the
same number of points (:func:`twin.batch.estimators.by_count`). A trial the batched fit
does not bring to convergence from the visit's noise-free calibration (its solution lies
far from it: a long route's drift moves the world frame) is calibrated as the campaign
does, by :func:`calib.calibrate_tsai` from its closed-form stages.
"""

from __future__ import annotations

import copy
import warnings
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from calib.camera import TsaiCameras
from calib.checks import DegenerateGeometryWarning, InputWarning
from calib.metrics import errors_3d_batch, pixel_errors_batch
from calib.point_errors import position_covariance_from_blocks
from calib.tsai import FULL_MIN_POINTS
from calib.tsai_lm import TsaiBatchResult, calibrate_tsai_batch
from twin.batch.estimators import (
    Calibrations,
    CpsStates,
    Estimators,
    Observations,
    ParentEstimates,
    by_count,
    calibrate_one,
    found,
    slot_rows,
)
from twin.instruments.marker_pose import MarkerPose as MarkerPoseBatch
from twin.instruments.marker_pose import led_positions_batch
from twin.localization.input_checks import ConvergenceWarning
from twin.localization.observation_batch import ChildObservationBatch, observe_child_batch
from twin.localization.sequence_batch import CpsBatch


class _BatchCps(CpsStates):
    def __init__(
        self,
        trials: int,
        children: Sequence[str],
        solver: str,
        rate: float | None,
        creep: float = 0.0,
    ):
        self.sequence = CpsBatch(
            list(children), trials, solver=solver, false_alarm_rate=rate, child_creep=creep
        )

    def children_moved(self, child: str, observations: Observations) -> None:
        self.sequence.children_moved([_observation(child, observations)])

    def parent_moved(self, observations: Sequence[tuple[str, Observations]]) -> NDArray[np.bool_]:
        with warnings.catch_warnings():
            # A few trials of thousands whose Gauss-Newton stops at its iteration limit
            # keep that estimate, as the campaign's CPS does; a warning a chunk says nothing
            # the trials' errors do not.
            warnings.simplefilter("ignore", ConvergenceWarning)
            solution = self.sequence.parent_moved([_observation(c, o) for c, o in observations])
        # A trial without a solution (children too close) is lost: its state is NaN and it
        # counts a failure at every later fix.
        return solution.inconsistent | solution.poor_geometry

    @property
    def parent(self) -> ParentEstimates:
        pose = self.sequence.parent
        return ParentEstimates(pose.yaw, pose.translation, pose.covariance)

    def child_position(self, child: str) -> NDArray[np.float64]:
        return self.sequence.child_position(child)[0]

    def on_rows(self, rows: NDArray[np.intp]) -> CpsStates:
        part = copy.copy(self)
        part.sequence = self.sequence.trials(rows)
        return part

    def put_rows(self, rows: NDArray[np.intp], part: CpsStates) -> None:
        assert isinstance(part, _BatchCps)
        self.sequence.set_trials(rows, part.sequence)

    def reset_rows(self, rows: NDArray[np.intp]) -> None:
        self.sequence.reset_trials(rows)


def _observation(child: str, o: Observations) -> ChildObservationBatch:
    return ChildObservationBatch(child, o.point, o.covariance)


class Vectorised(Estimators):
    """The campaign's estimators over all the trials at once (the batch's default)."""

    def observe(self, polar, spec, inclinometer, marker, false_alarm_rate) -> Observations:
        obs = observe_child_batch("child", polar, spec, inclinometer, marker=marker)
        pose = obs.marker_pose
        assert pose is not None
        return Observations(
            obs.point_level,
            obs.covariance,
            pose.rotation,
            pose.translation,
            pose.covariance,
            obs.marker_inconsistent(false_alarm_rate),
        )

    def cps(self, trials, children, solver, false_alarm_rate, child_creep=0.0) -> CpsStates:
        return _BatchCps(trials, children, solver, false_alarm_rate, child_creep)

    def leds(self, observations, marker):
        pose = MarkerPoseBatch(
            observations.rotation,
            observations.translation,
            observations.pose_covariance,
            np.zeros(len(observations.point)),
            None,
        )
        return led_positions_batch(pose, marker)

    def calibrate(self, points, pixels, image_size, start) -> Calibrations:
        t = len(points)
        kept = found(points, pixels)
        internal = {
            name: np.repeat(np.asarray(getattr(start, name), float)[None], t, axis=0)
            for name in ("f", "cx", "cy", "kappa1", "sx", "world2cam_r", "position")
        }
        position = np.full((t, 3), np.nan)
        std = np.full((t, 3), np.nan)
        sigma = np.full(t, np.nan)
        for trials, rows in by_count(kept):
            if rows.shape[1] < FULL_MIN_POINTS:
                continue  # too few points: not calibrated
            idx = trials[:, None]
            result = calibrate_tsai_batch(points[idx, rows], pixels[idx, rows], image_size, start)
            # A fit that wandered off (f or sx not positive) did not converge either.
            q = result.q
            ok = result.converged & np.isfinite(q).all(axis=1) & (q[:, 0] > 0) & (q[:, 3] > 0)
            cams = _select(result, np.flatnonzero(ok))
            for name in internal:
                internal[name][trials[ok]] = getattr(cams, name)
            position[trials[ok]] = result.position[ok]
            std[trials[ok]] = result.std[ok, 8:11]
            sigma[trials[ok]] = result.sigma_px[ok]
            # A trial whose solution lies far from the start (a long route's drift moves
            # the world frame) is calibrated as the campaign does, from closed-form stages.
            for k in trials[~ok]:
                with warnings.catch_warnings():
                    # Its warnings about the data are the campaign's to give, not a chunk's.
                    warnings.simplefilter("ignore", InputWarning)
                    warnings.simplefilter("ignore", DegenerateGeometryWarning)
                    one = calibrate_one(points[k][kept[k]], pixels[k][kept[k]], image_size)
                if one is not None:
                    cam, position[k], std[k], sigma[k] = one
                    for name in internal:
                        internal[name][k] = getattr(cam, name)
        cameras = TsaiCameras(**internal, image_size=start.image_size)
        made = np.isfinite(position).all(axis=1)
        return Calibrations(cameras, position, std, sigma, made, kept)

    def evaluate(self, calibrations, points, pixels):
        kept = found(points, pixels) & calibrations.calibrated[:, None]
        # Points a trial did not measure stand in as zeros and leave the means.
        pts = np.where(kept[..., None], points, 0.0)
        pix = np.where(kept[..., None], pixels, 0.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            n = kept.sum(axis=1)
            pixel = np.where(kept, pixel_errors_batch(calibrations.cameras, pts, pix), 0.0)
            error = np.where(kept, errors_3d_batch(calibrations.cameras, pts, pix), 0.0)
            return (
                np.where(n > 0, pixel.sum(axis=1) / n, np.nan),
                np.where(n > 0, error.sum(axis=1) / n, np.nan),
            )

    def points_effect(self, calibrations, points, stops, slots=None, shared=None):
        out = np.full((len(points), 3, 3), np.nan)
        for trials, rows in by_count(calibrations.kept & calibrations.calibrated[:, None]):
            if rows.shape[1] > 0:  # else not calibrated
                out[trials] = position_covariance_from_blocks(
                    _select(calibrations.cameras, trials),
                    points[trials[:, None], rows],
                    stops[trials],
                    slot_rows(rows, slots),
                    None if shared is None else shared[trials],
                )
        return out


def _select(cameras: TsaiCameras | TsaiBatchResult, trials: NDArray[np.intp]) -> TsaiCameras:
    """The cameras of some trials (of a batch of cameras or of calibrations)."""
    if isinstance(cameras, TsaiBatchResult):
        q, values = cameras.q[trials], cameras.values[trials]
        return TsaiCameras(
            q[:, 0],
            q[:, 1],
            q[:, 2],
            values[:, 4],
            q[:, 3],
            cameras.world2cam_r[trials],
            q[:, 8:11],
            cameras.image_size,
        )
    return TsaiCameras(
        cameras.f[trials],
        cameras.cx[trials],
        cameras.cy[trials],
        cameras.kappa1[trials],
        cameras.sx[trials],
        cameras.world2cam_r[trials],
        cameras.position[trials],
        cameras.image_size,
    )
