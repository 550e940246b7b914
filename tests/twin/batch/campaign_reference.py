"""A batch's visits calibrated as the campaign calibrates one trial's data set: scipy's
Tsai (:func:`calib.calibrate_tsai`), the Table III metrics (:func:`calib.evaluate`) and
the calibration's predicted error (its points' errors propagated to one camera:
:func:`calib.point_errors.covariance_from_point_errors`), trial by trial, on the points and
pixels each trial of the batch measured."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from calib import calibrate_tsai, evaluate
from calib.camera import TsaiCameras
from calib.covariance import own_position_variance
from calib.metrics import pose_errors
from calib.point_errors import covariance_from_point_errors
from twin.batch.estimators import found, slot_rows
from twin.batch.execute import BatchRun
from twin.batch.steps import Calibrate


@dataclass
class Reference:
    """(T,) each trial's campaign calibration of a visit (NaN where it made none)."""

    position_error: NDArray[np.float64]
    rotation_error: NDArray[np.float64]
    local_pixel: NDArray[np.float64]
    local_3d: NDArray[np.float64]
    predicted_calibration: NDArray[np.float64]

    @property
    def calibrated(self) -> NDArray[np.bool_]:
        return np.isfinite(self.position_error)


def campaign_calibration(run: BatchRun, step: Calibrate) -> Reference:
    """The visit ``step`` of ``run`` (every trial took its data set together)."""
    (data,) = run.datasets[("visit", step.camera, step.visit)]
    points, pixels = data.arrays(step.points)
    kept = found(points, pixels)
    truth = run.plan.cameras[step.camera]
    out = Reference(*(np.full(len(points), np.nan) for _ in range(5)))
    stops, slots, shared = data.stops(), data.slots()[: points.shape[1]], data.shared()
    for k in range(len(points)):
        pts, pix = points[k][kept[k]], pixels[k][kept[k]]
        if len(pts) < run.plan.scenario.campaign.min_points:
            continue
        try:
            result = calibrate_tsai(pts, pix, truth.image_size)
        except ValueError:
            continue
        camera = result.camera
        errors = pose_errors(TsaiCameras.from_cameras([camera]), truth)
        out.position_error[k] = errors.position_m[0]
        out.rotation_error[k] = errors.rotation_rad[0]
        metrics = evaluate(camera, pts, pix)
        out.local_pixel[k], out.local_3d[k] = metrics.pixel.mean, metrics.error_3d.mean
        # The points' joint covariance: a block a stop, plus their shared survey errors.
        cols = slot_rows(np.flatnonzero(kept[k])[None], slots)[0]
        blocks = stops[k]
        joint = np.zeros((len(blocks) * blocks.shape[1],) * 2)
        for i, block in enumerate(blocks):
            n = len(block)
            joint[i * n : (i + 1) * n, i * n : (i + 1) * n] = block
        if shared is not None:
            joint = joint + shared[k] @ shared[k].T
        cov = covariance_from_point_errors(camera, pts, joint[np.ix_(cols, cols)])
        std = result.std_by_name
        out.predicted_calibration[k] = np.sqrt(
            own_position_variance(
                np.array([[std["x"], std["y"], std["z"]]]),
                np.array([result.sigma_px]),
                run.advertised_led_px[step.camera],
                np.array([np.trace(cov[8:11, 8:11])]),
            )[0]
        )
    return out
