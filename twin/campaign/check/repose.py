"""A moved camera re-posed from the check's few points, its intrinsics kept.

The pose comes from the project's exterior-only calibration
(:func:`calib.tsai.calibrate_exterior`: PnP, then least squares on the pixels). How it
changed from the calibrated camera is given in :mod:`calib.pose_change`'s terms: the
optical centre's shift in W and the turn as a rotation vector in the calibrated camera's
axes.

The covariances are propagated from what the errors are known to be, not from the spread
of the fit's few residuals. With J_p and J_i the pixels' derivatives with respect to the
pose (turn, shift) and to the intrinsics (:func:`calib.camera_covariance.camera_jacobian`),
A = (J_p^T J_p)^-1 J_p^T, S the data's (2N, 2N) covariance and C the calibration's
(11, 11) one, the pose found is off by A e - A J_i d_i (e: the data's errors, d_i: the
kept intrinsics' error), so that to first order

- the change (new pose minus calibrated pose) has covariance
  A S A^T + M C M^T with M = [A J_i, I_6];
- the re-posed camera (the calibrated intrinsics, the new pose) has covariance
  K C_ii K^T + diag(0, A S A^T) with K = [I_5; -A J_i].
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from calib.camera import TsaiCamera
from calib.camera_covariance import INTRINSICS, N_CAMERA, POSE, camera_jacobian
from calib.pose_change import pose_change
from calib.tsai import calibrate_exterior


@dataclass(frozen=True)
class Repose:
    """A camera re-posed, and how it moved from its calibrated pose.

    Attributes:
        camera: the re-posed camera (the calibrated intrinsics, the new pose in W).
        shift_m: (3,) the optical centre's shift in W, m.
        turn_rad: (3,) the turn, a rotation vector in the calibrated camera's axes, rad.
        covariance: (6, 6) of the change (turn (3), rad; shift (3), m).
        camera_covariance: (11, 11) of the re-posed camera, in the terms of
            :data:`calib.camera_covariance.CAMERA_PARAMETERS`.
        sigma_px: the fit's residual standard deviation, px.
        notes: what the fit noted (few degrees of freedom, poor conditioning).
    """

    camera: TsaiCamera
    shift_m: NDArray[np.float64]
    turn_rad: NDArray[np.float64]
    covariance: NDArray[np.float64]
    camera_covariance: NDArray[np.float64]
    sigma_px: float
    notes: tuple[str, ...] = ()

    @property
    def turn_std_rad(self) -> NDArray[np.float64]:
        """(3,) standard deviation of each turn component, rad."""
        return np.sqrt(np.diag(self.covariance)[:3])

    @property
    def shift_std_m(self) -> NDArray[np.float64]:
        """(3,) standard deviation of each shift component, m."""
        return np.sqrt(np.diag(self.covariance)[3:])


def repose(
    calibrated: TsaiCamera,
    leds_world: NDArray[np.float64],
    pixels: NDArray[np.float64],
    data_cov: NDArray[np.float64],
    calibration_cov: NDArray[np.float64] | None = None,
) -> Repose:
    """Re-pose ``calibrated`` from LED points, keeping its intrinsics.

    Args:
        calibrated: the camera as calibrated.
        leds_world: (N, 3) LED positions in W, m; N >= 4 and not all on one line.
        pixels: (N, 2) their pixels, px.
        data_cov: (2N, 2N) covariance of the pixels' residuals from the data, px^2.
        calibration_cov: (11, 11) the calibrated camera's covariance (None: taken as
            exact).

    Raises:
        ValueError: too few points, or points on one line (from the calibration).
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the fit's notes are kept, not shown
        fit = calibrate_exterior(leds_world, pixels, calibrated)
    camera = fit.camera
    shift, turn = pose_change(calibrated, camera)
    cal = np.zeros((N_CAMERA, N_CAMERA)) if calibration_cov is None else calibration_cov
    jac = camera_jacobian(camera, leds_world)
    a = np.linalg.pinv(jac[:, POSE])
    a_ji = a @ jac[:, INTRINSICS]
    from_data = a @ data_cov @ a.T
    m = np.hstack([a_ji, np.eye(6)])
    k = np.vstack([np.eye(5), -a_ji])
    own = k @ cal[INTRINSICS, INTRINSICS] @ k.T
    own[POSE, POSE] += from_data
    change = from_data + m @ cal @ m.T
    return Repose(
        camera=camera,
        shift_m=shift,
        turn_rad=turn,
        covariance=0.5 * (change + change.T),
        camera_covariance=0.5 * (own + own.T),
        sigma_px=fit.sigma_px,
        notes=fit.notes,
    )
