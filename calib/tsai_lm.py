"""Levenberg-Marquardt for Tsai's calibration of T data sets at once: the full optimisation
of :mod:`calib.tsai` as arrays over Monte-Carlo trials.

:func:`calibrate_tsai_batch` refines the 11 internal parameters of
:mod:`calib.tsai_parameters` (f, cx, cy, sx, kappa1 * kscale, rotation vector, optical
centre C) of T independent data
sets of the same size, each from a given start (a Monte-Carlo batch passes the noise-free
calibration of its visit), by Levenberg-Marquardt on the same reprojection residual, with
the analytic Jacobian: (T, 2N, 11) Jacobians, (T, 11, 11) normal equations solved as a
stack, a damping and a convergence test per trial, in blocks of trials. A trial that has
converged leaves the computation; no arithmetic mixes trials, so trial k of a batch is bit
for bit a batch of trial k alone.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.camera import TsaiCamera, TsaiCameras
from calib.checks import check_image_size
from calib.covariance import normal_inverse, solve_or_nan
from calib.rotation import rotvec2matrix_batch
from calib.tsai import FULL_MIN_POINTS
from calib.tsai_parameters import (
    N_TSAI,
    TSAI_PARAMETERS,
    kappa_scale,
    pack,
    reported_batch,
    reporting_jacobian,
    residuals_and_jacobian,
)

_LAMBDA_START = 1e-6  # the damping of the column-scaled normal equations at the start
_LAMBDA_STALL = 1e10  # a trial whose damping grows past this makes no progress: it stops
_NEAR = 0.3  # standard deviations from the minimum: the secant Hessian is used nearer
# A step is taken unless it raises the residual sum of squares by more than this relative
# amount: the rounding of the sum (~1e-13 relative) hides the last decreases near the
# minimum, where the steps are a few 1e-6 standard deviations and the Gauss-Newton
# iteration still contracts.
_COST_ROUNDING = 1e-12


@dataclass(frozen=True, eq=False)
class TsaiBatchResult:
    """T calibrations with Tsai's model, one per trial.

    Attributes:
        q: (T, 11) internal parameters [f, cx, cy, sx, kappa1 * kscale, rotation vector (3),
            optical centre C (3)], as in :mod:`calib.tsai`.
        values: (T, 11) reported parameters in the order of ``TSAI_PARAMETERS`` (f_px, cx,
            cy, sx, kappa1_px in 1/px^2, Tsai's angles rx, ry, rz in rad, x, y, z in m), as
            ``CalibrationResult.values``.
        covariance: (T, 11, 11) covariance of ``values``, as ``CalibrationResult.covariance``.
        covariance_q: (T, 11, 11) covariance of ``q``: sigma^2 (J^T J)^-1.
        sigma_px: (T,) residual standard deviation sqrt(|r|^2 / dof), px.
        dof: degrees of freedom of each fit, 2N - 11.
        converged: (T,) the trial met the convergence test within the iterations allowed,
            every point projects in front of its camera, and the data determine all the
            parameters (else the covariances are NaN).
        iterations: (T,) Levenberg-Marquardt iterations of each trial (steps tried).
        world2cam_r: (T, 3, 3) rotations from the world to the camera frame.
        image_size: (width, height), px.
    """

    q: NDArray[np.float64]
    values: NDArray[np.float64] = field(repr=False)
    covariance: NDArray[np.float64] = field(repr=False)
    covariance_q: NDArray[np.float64] = field(repr=False)
    sigma_px: NDArray[np.float64] = field(repr=False)
    dof: int
    converged: NDArray[np.bool_] = field(repr=False)
    iterations: NDArray[np.int_] = field(repr=False)
    world2cam_r: NDArray[np.float64] = field(repr=False)
    image_size: tuple[int, int]

    parameter_names = TSAI_PARAMETERS

    def __len__(self) -> int:
        return len(self.q)

    @property
    def position(self) -> NDArray[np.float64]:
        """(T, 3) optical centres in the world frame, m."""
        return self.q[:, 8:11]

    @property
    def position_covariance(self) -> NDArray[np.float64]:
        """(T, 3, 3) covariance of the optical centres, m^2."""
        return self.covariance_q[:, 8:11, 8:11]

    @property
    def std(self) -> NDArray[np.float64]:
        """(T, 11) standard deviations of ``values``."""
        return np.sqrt(np.diagonal(self.covariance, axis1=1, axis2=2))

    @property
    def cameras(self) -> TsaiCameras:
        """The T calibrated cameras (for :mod:`calib.metrics`)."""
        return TsaiCameras(
            self.q[:, 0],
            self.q[:, 1],
            self.q[:, 2],
            self.values[:, 4],
            self.q[:, 3],
            self.world2cam_r,
            self.position,
            self.image_size,
        )

    def camera(self, k: int) -> TsaiCamera:
        """Trial k's calibrated camera."""
        return self.cameras.camera(k)


def _check_data(
    points: ArrayLike, pixels: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(T, N, 3) or shared (N, 3) points and (T, N, 2) pixels -> both as (T, N, ...)."""
    uv = np.asarray(pixels, dtype=float)
    if uv.ndim != 3 or uv.shape[2] != 2:
        raise ValueError(f"pixels must have shape (T, N, 2), got {uv.shape}")
    n_t, n = uv.shape[:2]
    p = np.asarray(points, dtype=float)
    if p.shape not in ((n_t, n, 3), (n, 3)):
        raise ValueError(f"points must have shape ({n_t}, {n}, 3) or ({n}, 3), got {p.shape}")
    p = np.ascontiguousarray(np.broadcast_to(p, (n_t, n, 3)))
    if not (np.isfinite(p).all() and np.isfinite(uv).all()):
        raise ValueError("points and pixels must be finite")
    if n < FULL_MIN_POINTS:
        raise ValueError(
            f"Tsai's full optimisation of {N_TSAI} parameters needs at least "
            f"{FULL_MIN_POINTS} points, got {n}"
        )
    return p, uv


def _start(start: TsaiCamera | ArrayLike, size: tuple[int, int], n_t: int) -> NDArray[np.float64]:
    """A camera, (11,) or (T, 11) internal parameters -> (T, 11) starts."""
    if isinstance(start, TsaiCamera):
        if start.image_size != size:
            raise ValueError(
                f"the start camera's image size {start.image_size} is not {size}: its kappa1 "
                "would be scaled differently"
            )
        start = pack(start)
    q0 = np.asarray(start, dtype=float)
    if q0.shape not in ((N_TSAI,), (n_t, N_TSAI)):
        raise ValueError(f"start must be a TsaiCamera or have shape ({n_t}, 11), got {q0.shape}")
    if not np.isfinite(q0).all():
        raise ValueError("the start parameters must be finite")
    return np.array(np.broadcast_to(q0, (n_t, N_TSAI)))


def _normal_equations(
    jac: NDArray[np.float64], res: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """J^T J (T, P, P) and the gradient J^T r (T, P) of half the residual sum of squares."""
    jt = np.swapaxes(jac, 1, 2)
    return jt @ jac, (jt @ res[:, :, None])[:, :, 0]


def _secant_update(
    s_mat: NDArray[np.float64],
    step: NDArray[np.float64],
    jac: NDArray[np.float64],
    grad: NDArray[np.float64],
    jac_new: NDArray[np.float64],
    res_new: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Update the estimate S (T, P, P) of the second-order part sum r_i d^2 r_i of the
    Hessian after a step (T, P) (Dennis, Gay and Welsch's NL2SOL update, with its sizing).

    S is made to satisfy the secant equation S step = (J_new - J)^T r_new, the change of
    J^T r at fixed residuals; where the step does not raise the gradient along itself
    (y . step <= 0, y the change of the gradient) S is left as it is.
    """
    g_new = (np.swapaxes(jac_new, 1, 2) @ res_new[:, :, None])[:, :, 0]
    y_sharp = g_new - (np.swapaxes(jac, 1, 2) @ res_new[:, :, None])[:, :, 0]
    y = g_new - grad
    s_step = (s_mat @ step[:, :, None])[:, :, 0]
    curv = np.sum(step * s_step, axis=1)
    ratio = np.abs(np.sum(step * y_sharp, axis=1)) / np.where(curv != 0.0, np.abs(curv), 1.0)
    size = np.where(curv != 0.0, np.minimum(1.0, ratio), 1.0)
    s_mat, s_step = s_mat * size[:, None, None], s_step * size[:, None]
    w = y_sharp - s_step
    ys = np.sum(y * step, axis=1)
    ok = ys > 0.0
    ys = np.where(ok, ys, 1.0)
    wy = w[:, :, None] * y[:, None, :]
    yy = y[:, :, None] * y[:, None, :]
    upd = (wy + np.swapaxes(wy, 1, 2)) / ys[:, None, None]
    upd -= (np.sum(w * step, axis=1) / ys**2)[:, None, None] * yy
    return np.where(ok[:, None, None], s_mat + upd, s_mat)


@dataclass
class _Fit:
    """The state of the trials still being fitted (rows: those trials)."""

    index: NDArray[np.int_]
    q: NDArray[np.float64]
    res: NDArray[np.float64]
    jac: NDArray[np.float64]
    cost: NDArray[np.float64]
    lam: NDArray[np.float64]
    s_mat: NDArray[np.float64]
    near: NDArray[np.bool_]
    points: NDArray[np.float64]
    pixels: NDArray[np.float64]

    def keep(self, rows: NDArray[np.bool_]) -> None:
        """Keep only these rows."""
        for name in self.__dataclass_fields__:
            setattr(self, name, getattr(self, name)[rows])


@dataclass
class _Solution:
    """Where each trial stopped: q (T, 11), J^T J (T, 11, 11), the residual sum of squares
    (T,), px^2, whether it converged, and its iterations."""

    q: NDArray[np.float64]
    normal: NDArray[np.float64]
    cost: NDArray[np.float64]
    converged: NDArray[np.bool_]
    iterations: NDArray[np.int_]

    @classmethod
    def concatenate(cls, parts: list[_Solution]) -> _Solution:
        """The solutions of consecutive blocks of trials as one."""
        return cls(
            *(np.concatenate([getattr(p, f) for p in parts]) for f in cls.__dataclass_fields__)
        )

    def record(self, fit: _Fit, rows: NDArray[np.bool_], normal: NDArray, done: NDArray) -> None:
        """Record the trials of these rows of ``fit`` (normal: their J^T J)."""
        i = fit.index[rows]
        self.q[i], self.normal[i], self.cost[i] = fit.q[rows], normal[rows], fit.cost[rows]
        self.converged[i] = done[rows]


@dataclass
class _Steps:
    """One iteration's model of the trials being fitted (rows: those trials)."""

    normal: NDArray[np.float64]  # J^T J, (T, P, P)
    grad: NDArray[np.float64]  # J^T r, (T, P)
    step: NDArray[np.float64]  # the damped step to try, (T, P)
    gauss: NDArray[np.float64]  # squared length of the Gauss-Newton step, sigma^2 units
    augmented: NDArray[np.float64]  # of the step of the augmented model, sigma^2 units
    solved: NDArray[np.bool_]  # the systems were regular

    def keep(self, rows: NDArray[np.bool_]) -> None:
        """Keep only these rows."""
        for name in self.__dataclass_fields__:
            setattr(self, name, getattr(self, name)[rows])


def _model_steps(fit: _Fit, dof: int, min_sigma_px: float) -> _Steps:
    """The Gauss-Newton step, the step of the augmented model (J^T J plus the secant S of
    the trials near their minimum) and that step damped by lambda, on the normal
    equations scaled by the column norms of J; the first two measured in the fit's
    standard deviations: |dq|_A^2 / sigma^2, sigma^2 = max(|r|^2 / dof, min_sigma_px^2)."""
    a, g = _normal_equations(fit.jac, fit.res)
    d = np.sqrt(np.diagonal(a, axis1=1, axis2=2))
    d = np.where(d > 0.0, d, 1.0)
    dd = d[:, :, None] * d[:, None, :]
    model = (a + fit.near[:, None, None] * fit.s_mat) / dd
    damped = model + fit.lam[:, None, None] * np.eye(N_TSAI)
    systems = np.stack([a / dd, model, damped], axis=1)
    y = solve_or_nan(systems, np.broadcast_to((g / d)[:, None, :, None], (*systems.shape[:3], 1)))
    y = y[..., 0]
    sigma2 = np.maximum(fit.cost / dof, min_sigma_px**2)
    return _Steps(
        normal=a,
        grad=g,
        step=-y[:, 2] / d,
        gauss=np.sum(g / d * y[:, 0], axis=1) / sigma2,
        augmented=np.einsum("ti,tij,tj->t", y[:, 1], a / dd, y[:, 1]) / sigma2,
        solved=np.isfinite(y).all(axis=(1, 2)),
    )


def _take_steps(fit: _Fit, steps: _Steps, kscale: float) -> None:
    """Try each trial's step: take it unless it raises |r|^2 (beyond rounding), update
    the secant S and the damping."""
    q_new = fit.q + steps.step
    res_new, jac_new = residuals_and_jacobian(q_new, fit.points, fit.pixels, kscale)
    cost_new = np.sum(res_new * res_new, axis=1)
    better = cost_new <= fit.cost * (1.0 + _COST_ROUNDING)
    s_new = _secant_update(fit.s_mat, steps.step, fit.jac, steps.grad, jac_new, res_new)
    fit.s_mat = np.where(better[:, None, None], s_new, fit.s_mat * ~fit.near[:, None, None])
    fit.q[better], fit.res[better], fit.jac[better], fit.cost[better] = (
        q_new[better], res_new[better], jac_new[better], cost_new[better],
    )  # fmt: skip
    fit.lam = np.where(better, fit.lam / 10.0, np.maximum(fit.lam * 10.0, _LAMBDA_START))
    fit.near = better & (steps.gauss < _NEAR**2)


def _levenberg_marquardt(
    q0: NDArray[np.float64],
    points: NDArray[np.float64],
    pixels: NDArray[np.float64],
    kscale: float,
    max_iterations: int,
    xtol: float,
    min_sigma_px: float,
) -> _Solution:
    """Minimise each trial's residual sum of squares |r|^2 from q0 (T, 11).

    Levenberg-Marquardt on the column-scaled normal equations. Near its minimum (within
    ``_NEAR`` standard deviations) a trial adds to J^T J the secant estimate of the
    second-order part of the Hessian (:func:`_secant_update`): where the residuals bend a
    weakly determined direction (cx against the rotation), Gauss-Newton alone contracts by
    as little as 0.75 per iteration. A step with it that fails drops the estimate.

    A trial converges when the steps to the minimum of both models (Gauss-Newton and
    augmented) are at most ``xtol`` of its standard deviations long (see
    :func:`_model_steps`). It stops there without taking the step; so does a trial whose
    damping passes ``_LAMBDA_STALL``, unconverged.
    """
    n_t = len(q0)
    dof = 2 * pixels.shape[1] - N_TSAI
    res, jac = residuals_and_jacobian(q0, points, pixels, kscale)
    fit = _Fit(
        np.arange(n_t), q0.copy(), res, jac, np.sum(res * res, axis=1),
        np.full(n_t, _LAMBDA_START), np.zeros((n_t, N_TSAI, N_TSAI)), np.zeros(n_t, bool),
        points, pixels,
    )  # fmt: skip
    out = _Solution(
        q0.copy(), np.zeros((n_t, N_TSAI, N_TSAI)), fit.cost.copy(),
        np.zeros(n_t, dtype=bool), np.zeros(n_t, dtype=int),
    )  # fmt: skip
    for it in range(max_iterations + 1):
        steps = _model_steps(fit, dof, min_sigma_px)
        done = (steps.gauss <= xtol**2) & (steps.augmented <= xtol**2)
        leaving = done | (fit.lam > _LAMBDA_STALL) | ~steps.solved | (it == max_iterations)
        if leaving.any():
            out.record(fit, leaving, steps.normal, done)
            fit.keep(~leaving)
            steps.keep(~leaving)
        if len(fit.index) == 0:
            break
        _take_steps(fit, steps, kscale)
        out.iterations[fit.index] += 1
    return out


def calibrate_tsai_batch(
    points: ArrayLike,
    pixels: ArrayLike,
    image_size: tuple[int, int],
    start: TsaiCamera | ArrayLike,
    *,
    max_iterations: int = 100,
    xtol: float = 1e-6,
    min_sigma_px: float = 1e-4,
    block: int = 64,
) -> TsaiBatchResult:
    """Calibrate T data sets with Tsai's model at once, each from a start close to it.

    The full optimisation of :func:`calib.tsai.calibrate_tsai` (same internal parameters,
    same reprojection residual, same covariance) for T trials of N points each, without
    its closed-form stages: every trial starts from ``start``. A Monte-Carlo batch passes
    the noise-free calibration of the visit, within millimetres of every trial's solution.

    Args:
        points: (T, N, 3) world points, m; or (N, 3) shared by all trials.
        pixels: (T, N, 2) observed pixels (OpenCV convention).
        image_size: (width, height), px.
        start: a camera of this image size, or (11,) / (T, 11) internal parameters.
        max_iterations: Levenberg-Marquardt iterations at most, per trial.
        xtol: a trial has converged when the minimum lies within ``xtol`` of its own
            standard deviations (the Mahalanobis length of the step to the minimum of its
            local model).
        min_sigma_px: residual standard deviations below this (noise-free data) count as
            this in the convergence test, px.
        block: trials fitted together; the results do not depend on it. Blocks of 64
            keep the temporaries small enough that glibc's allocator reuses them instead of
            returning them to the system and faulting them in again: 1.2 times the rate
            of 1000 at once (with the allocator told not to trim, blocks of 256-512 are
            fastest, 1.5 times).

    Returns:
        The T calibrations; ``converged`` tells which met the test.

    Each trial converges to the minimum of the basin its start lies in. Where the geometry
    is weak (20 points at 0.3 px: cx uncertain by 20-40 px) a data set can have several
    minima, and ``calibrate_tsai``, which starts from its closed-form stages, may find
    another one.
    """
    size = check_image_size(image_size)
    p3, uv = _check_data(points, pixels)
    n_t, n = uv.shape[:2]
    q0 = _start(start, size, n_t)
    kscale = kappa_scale(size)
    dof = 2 * n - N_TSAI
    if block < 1:
        raise ValueError(f"block must be at least 1, got {block}")
    blocks = [slice(i, i + block) for i in range(0, n_t, block)]
    fit = (kscale, max_iterations, xtol, min_sigma_px)
    sol = _Solution.concatenate([_levenberg_marquardt(q0[b], p3[b], uv[b], *fit) for b in blocks])
    q = sol.q
    sigma2 = sol.cost / dof
    cov_q = sigma2[:, None, None] * normal_inverse(sol.normal)
    g = reporting_jacobian(q, kscale)
    rot = rotvec2matrix_batch(q[:, 5:8])
    values = reported_batch(q, kscale)
    z = (p3 - q[:, None, 8:11]) @ rot[:, 2:3, :].transpose(0, 2, 1)
    return TsaiBatchResult(
        q=q,
        values=values,
        covariance=g @ cov_q @ np.swapaxes(g, 1, 2),
        covariance_q=cov_q,
        sigma_px=np.sqrt(sigma2),
        dof=dof,
        converged=sol.converged & (z[:, :, 0] > 0).all(axis=1) & np.isfinite(cov_q[:, 0, 0]),
        iterations=sol.iterations,
        world2cam_r=rot,
        image_size=size,
    )
