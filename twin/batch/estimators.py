"""The campaign's estimators over the trials of a batch, as array code: what the campaign
computes from one trial's measurements, for T trials at once.

- :func:`observe`: a child's reference point, its covariance and its marker's pose from
  three levelled cube shots (:func:`twin.localization.observation.observe_child_batch`);
- :func:`leds`: a stop's LED positions from its marker's pose
  (:func:`twin.instruments.marker_pose.led_positions_batch`);
- :func:`calibrate`, :func:`evaluate`, :func:`truth_errors`: Tsai's calibration of a visit
  (:func:`calib.tsai_lm.calibrate_tsai_batch`, from the visit's noise-free calibration)
  and the Table III metrics (:mod:`calib.metrics`);
- :func:`points_effect`: the calibrated camera's error from its points' errors.

The CPS state is :class:`twin.localization.joint_state.CpsBatch` itself. The positioning
numbers are the campaign's scalar code's bit for bit, the calibrations scipy's
(:func:`calib.calibrate_tsai`) to a small fraction of their standard deviations (the tests
hold them to it); no trial's numbers depend on the other trials of its batch.

Trials that gave up stops calibrate on fewer points: trials are fitted in groups of the
same number of points (:func:`by_count`). A trial the batched fit does not bring to
convergence from the visit's noise-free calibration (its solution lies far from it: a long
route's drift moves the world frame) is calibrated as the campaign does, by
:func:`calib.calibrate_tsai` from its closed-form stages.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from calib import calibrate_tsai
from calib.camera import TsaiCamera, TsaiCameras
from calib.checks import DegenerateGeometryWarning, InputWarning
from calib.metrics import errors_3d_batch, pixel_errors_batch, pose_errors
from calib.point_errors import position_covariance_from_blocks
from calib.rotation import rot_z
from calib.tsai import FULL_MIN_POINTS
from calib.tsai_lm import TsaiBatchResult, calibrate_tsai_batch
from twin.instruments.marker import MarkerAssembly
from twin.instruments.marker_pose import MarkerPose, led_positions_batch
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec
from twin.localization.observation import observe_child_batch


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


def observe(
    polar: NDArray[np.float64],
    spec: TotalStationSpec,
    inclinometer: InclinometerSpec | None,
    marker: MarkerAssembly,
    false_alarm_rate: float | None,
) -> Observations:
    """A child's observations from (T, 3, 3) levelled polar shots at its three cubes."""
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


def leds(
    observations: Observations, marker: MarkerAssembly
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(T, N_led, 3) LED positions in the levelled frame and their (T, 3N, 3N) covariance
    from the marker's pose."""
    pose = MarkerPose(
        observations.rotation,
        observations.translation,
        observations.pose_covariance,
        np.zeros(len(observations.point)),
        None,
    )
    return led_positions_batch(pose, marker)


def calibrate(
    points: NDArray[np.float64],
    pixels: NDArray[np.float64],
    image_size: tuple[int, int],
    start: TsaiCamera,
) -> Calibrations:
    """Tsai's calibration of (T, N, 3) points and (T, N, 2) pixels from the visit's
    noise-free calibration ``start`` (NaN rows are points a trial did not measure:
    :func:`found`)."""
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


def evaluate(
    calibrations: Calibrations, points: NDArray[np.float64], pixels: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(T,) mean pixel error, px, and (T,) mean 3D error, m, of each trial's camera on its
    (T, M, 3) points and (T, M, 2) pixels (NaN where not calibrated)."""
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


def points_effect(
    calibrations: Calibrations,
    points: NDArray[np.float64],
    stops: NDArray[np.float64],
    slots: NDArray[np.intp] | None = None,
    shared: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """(T, 3, 3) covariance of each calibrated camera's centre, m^2, from the errors of its
    (T, n, 3) points (NaN where not calibrated), to first order at the calibrated camera
    (:func:`calib.point_errors.position_covariance_from_blocks`).

    The points' joint covariance is block-diagonal, one (T, S, k, k) block a stop (its LEDs
    share the marker's measured pose), in a layout of S k / 3 points: ``slots`` (n,) says
    where each point sits in it (default: the first n, in order; a stop that shows only
    some LEDs leaves the others' rows out of the data); plus ``S S^T`` for the (T, S k, M)
    ``shared`` loadings of the layout on errors common to its stops (a child's marker
    survey: :func:`twin.instruments.marker_pose.survey_layout`)."""
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


def truth_errors(
    calibrations: Calibrations, truth: TsaiCamera
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(T,) position error, m, and (T,) rotation error, rad, against the true camera
    (NaN where not calibrated)."""
    errors = pose_errors(calibrations.cameras, truth)
    failed = ~calibrations.calibrated
    return (
        np.where(failed, np.nan, errors.position_m),
        np.where(failed, np.nan, errors.rotation_rad),
    )


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
