"""Is a camera where its calibration says? A chi-square test of its LED pixels.

The residuals are the observed LED pixels minus the calibrated camera's projections of the
LEDs' measured 3D positions. If the camera has not moved they are noise: the detector's
pixel noise plus the 3D positions' error seen through the camera, with the joint
covariance S (:func:`twin.campaign.check.covariance.residual_covariance`). Then

    chi2 = r^T S^-1 r

follows a chi-square distribution with 2N degrees of freedom (N LEDs), and the camera is
declared moved when chi2 exceeds its quantile at 1 - alpha: an unmoved camera is called
moved with probability alpha, the false-alarm rate.

The calibrated model has its own error, the same for every point of the check: where its
covariance is known (``twin run`` writes it into each camera's JSON file), it is added to
S through the pixels' derivatives with respect to the camera
(:func:`calib.camera_covariance.camera_jacobian`). Without it a calibration that is off by
more than the check's noise reads as a move.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2 as chi2_distribution

from calib.camera import TsaiCamera

DEFAULT_FALSE_ALARM_RATE = 1e-3
"""Probability that an unmoved camera is declared moved (``twin check
--false-alarm-rate``): one camera in a thousand checks."""


@dataclass(frozen=True)
class Consistency:
    """The chi-square test of one camera's check data against its calibrated model.

    Attributes:
        residuals_px: (N, 2) observed minus projected pixels, px.
        chi2: the statistic r^T S^-1 r. dof: its degrees of freedom, 2N.
        false_alarm_rate: alpha. threshold: the chi-square quantile at 1 - alpha.
        p_value: probability of a chi2 at least this large for an unmoved camera.
    """

    residuals_px: NDArray[np.float64]
    chi2: float
    dof: int
    false_alarm_rate: float
    threshold: float
    p_value: float

    @property
    def moved(self) -> bool:
        """Whether the test says the camera moved (chi2 above the threshold)."""
        return self.chi2 > self.threshold


def check_false_alarm_rate(alpha: float) -> float:
    """``alpha`` if it is a probability strictly between 0 and 1; ValueError naming it
    otherwise."""
    a = float(alpha)
    if not 0.0 < a < 1.0:
        raise ValueError(f"the false-alarm rate must lie strictly between 0 and 1, got {alpha!r}")
    return a


def chi_square_test(
    camera: TsaiCamera,
    leds_world: NDArray[np.float64],
    pixels: NDArray[np.float64],
    residual_cov: NDArray[np.float64],
    false_alarm_rate: float = DEFAULT_FALSE_ALARM_RATE,
) -> Consistency:
    """The chi-square test of observed pixels against ``camera``'s projections.

    Args:
        camera: the calibrated camera.
        leds_world: (N, 3) measured LED positions in W, m.
        pixels: (N, 2) where the camera found them, px.
        residual_cov: (2N, 2N) covariance of the residuals, px^2.
        false_alarm_rate: alpha, in (0, 1).

    Raises:
        ValueError: a false-alarm rate outside (0, 1), no points, or an LED behind the
            calibrated camera.
    """
    alpha = check_false_alarm_rate(false_alarm_rate)
    if len(leds_world) == 0:
        raise ValueError("the chi-square test needs at least one LED point")
    projected = camera.project_or_nan(leds_world)
    if not np.all(np.isfinite(projected)):
        raise ValueError("an LED lies behind the calibrated camera: it cannot have seen it")
    residuals = np.asarray(pixels, dtype=float) - projected
    r = residuals.ravel()
    chi2 = float(r @ np.linalg.solve(residual_cov, r))
    dof = r.size
    return Consistency(
        residuals_px=residuals,
        chi2=chi2,
        dof=dof,
        false_alarm_rate=alpha,
        threshold=float(chi2_distribution.ppf(1.0 - alpha, dof)),
        p_value=float(chi2_distribution.sf(chi2, dof)),
    )
