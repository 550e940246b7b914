"""The result of a calibration: the camera, its parameters with covariance, and metrics."""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from calib.checks import DegenerateGeometryWarning, InputWarning
from calib.covariance import least_squares_covariance, propagate_covariance
from calib.duplicates import duplicates_note
from calib.metrics import Metrics, evaluate
from calib.plausibility import Implausibility, check_magnitudes


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """A calibrated camera with the uncertainty of its parameters.

    Attributes:
        model: "tsai", "tsai-exterior" or "opencv".
        camera: the calibrated camera (a TsaiCamera or an OpenCVCamera).
        parameter_names: names of the reported parameters, in SI units (rotation angles in
            rad about the world X, Y, Z axes; position of the optical centre in m).
        values: (P,) reported parameter values.
        covariance: (P, P) covariance of the reported parameters, scaled by the residual
            variance. NaN where the data do not determine a parameter.
        sigma_px: residual standard deviation sqrt(|r|^2 / dof), px.
        dof: degrees of freedom of the fit (2N - number of free parameters).
        metrics: Table III metrics on the calibration data themselves.
        initial_camera: the camera from the closed-form stages (None if not applicable).
        notes: messages a user should read (few degrees of freedom, poor conditioning,
            duplicate rows).
        duplicates: number of input rows that repeated an earlier row exactly (same x, y,
            z, u, v); merged unless ``duplicates_kept``.
        duplicates_kept: the duplicates were fitted as independent measurements.
        implausible: magnitudes no real calibration produces (a camera kilometres from
            its points: coordinates in the wrong unit); their notes are among ``notes``.
    """

    model: str
    camera: Any
    parameter_names: tuple[str, ...]
    values: NDArray[np.float64]
    covariance: NDArray[np.float64]
    sigma_px: float
    dof: int
    metrics: Metrics
    initial_camera: Any = None
    notes: tuple[str, ...] = field(default_factory=tuple)
    duplicates: int = 0
    duplicates_kept: bool = False
    implausible: tuple[Implausibility, ...] = ()

    @property
    def std(self) -> NDArray[np.float64]:
        """(P,) standard deviations of the reported parameters."""
        return np.sqrt(np.diag(self.covariance))

    @property
    def parameters(self) -> dict[str, float]:
        """Reported parameter values by name (SI units)."""
        return dict(zip(self.parameter_names, self.values.tolist(), strict=True))

    @property
    def std_by_name(self) -> dict[str, float]:
        """Standard deviations by parameter name (SI units)."""
        return dict(zip(self.parameter_names, self.std.tolist(), strict=True))

    @property
    def n_points(self) -> int:
        """Number of correspondences used."""
        return self.metrics.n_points


FEW_DOF = 10  # below this many degrees of freedom the standard deviations are shaky
ILL_CONDITIONED = 1e8  # condition number of the (column-scaled) normal equations


LARGE_RESIDUAL_PX = 5.0  # a residual sigma above this suggests wrong correspondences


def fit_notes(dof: int, condition: float, sigma_px: float = 0.0) -> list[str]:
    """Messages about a fit that a user should read: few degrees of freedom, bad geometry,
    residuals too large for correct correspondences."""
    notes = []
    if sigma_px > LARGE_RESIDUAL_PX:
        notes.append(
            f"the residuals are large (sigma {sigma_px:.3g} px): check the correspondences, "
            "the units and the image size"
        )
    if dof < FEW_DOF:
        notes.append(
            f"the fit has only {dof} degrees of freedom (2 x points - parameters); the "
            "standard deviations rest on few residuals: use more points"
        )
    if condition > ILL_CONDITIONED:
        notes.append(
            f"the normal equations are ill-conditioned (condition number {condition:.3g}); "
            "some parameters are poorly determined by this point geometry"
        )
    return notes


def _implausible(camera: Any, points_3d: NDArray[np.float64]) -> list[Implausibility]:
    """:func:`check_magnitudes` for a Tsai or an OpenCV camera."""
    if hasattr(camera, "kappa1"):
        f, sx, kappa1 = float(camera.f), float(camera.sx), float(camera.kappa1)
    else:
        f, sx, kappa1 = float(camera.fy), float(camera.fx / camera.fy), None
    return check_magnitudes(camera.position, f, sx, camera.image_size, points_3d, kappa1)


def result_from_fit(
    model: str,
    camera: Any,
    names: tuple[str, ...],
    q: NDArray[np.float64],
    jac: NDArray[np.float64],
    residuals: NDArray[np.float64],
    reported: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    steps: NDArray[np.float64],
    points_3d: NDArray[np.float64],
    pixels: NDArray[np.float64],
    initial_camera: Any = None,
    *,
    duplicates: int = 0,
    duplicates_kept: bool = False,
) -> CalibrationResult:
    """Turn a least-squares solution into a result.

    The covariance of the internal parameters q is sigma^2 (J^T J)^-1; it is propagated to
    the reported parameters ``reported(q)`` (whose rotation angles are named rx, ry, rz),
    the Table III metrics are evaluated, the magnitudes are checked for plausibility
    (:mod:`calib.plausibility`), and the notes are emitted as warnings.

    Args:
        model: the model's name. camera: the calibrated camera.
        names: (P,) names of the reported parameters.
        q: (Q,) solution in the optimiser's parameters. jac: (M, Q) Jacobian there.
        residuals: (M,) residuals there, px. reported: q -> (P,) reported parameters.
        steps: (Q,) finite-difference steps for the propagation.
        points_3d, pixels: the correspondences, (N, 3) m and (N, 2) px.
        initial_camera: the closed-form start, if any.
        duplicates: number of input rows that repeated an earlier one exactly.
        duplicates_kept: whether those rows are among ``points_3d`` and ``pixels``.
    """
    cov_q, sigma2, dof = least_squares_covariance(jac, residuals)
    angle_mask = np.isin(names, ("rx", "ry", "rz"))
    covariance = propagate_covariance(cov_q, reported, q, steps, angle_mask)
    condition = float(np.linalg.cond(jac / np.linalg.norm(jac, axis=0)) ** 2)
    sigma = float(np.sqrt(sigma2)) if dof > 0 else float("nan")
    notes = fit_notes(dof, condition, sigma if dof > 0 else 0.0)
    for n in notes:
        warnings.warn(n, DegenerateGeometryWarning, stacklevel=3)
    if duplicates:
        n_rows = len(points_3d) + (0 if duplicates_kept else duplicates)
        notes.append(duplicates_note(duplicates, n_rows, duplicates_kept))
        warnings.warn(notes[-1], InputWarning, stacklevel=3)
    implausible = _implausible(camera, points_3d)
    for finding in implausible:
        notes.append(finding.note)
        warnings.warn(finding.note, InputWarning, stacklevel=3)
    return CalibrationResult(
        model=model,
        camera=camera,
        parameter_names=names,
        values=reported(q),
        covariance=covariance,
        sigma_px=sigma,
        dof=dof,
        metrics=evaluate(camera, points_3d, pixels),
        initial_camera=initial_camera,
        notes=tuple(notes),
        duplicates=duplicates,
        duplicates_kept=duplicates_kept,
        implausible=tuple(implausible),
    )
