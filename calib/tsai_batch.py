"""Tsai calibration of T data sets at once: the full optimisation of :mod:`calib.tsai` as
arrays over Monte-Carlo trials.

:func:`calibrate_tsai_batch` refines the 11 internal parameters of :mod:`calib.tsai`
(f, cx, cy, sx, kappa1 * kscale, rotation vector, optical centre C) of T independent data
sets of the same size, each from a given start (a Monte-Carlo batch passes the noise-free
calibration of its visit), by Levenberg-Marquardt on the same reprojection residual, with
the analytic Jacobian: (T, 2N, 11) Jacobians, (T, 11, 11) normal equations solved as a
stack, a damping and a convergence test per trial, in blocks of trials. A trial that has
converged leaves the computation; no arithmetic mixes trials, so trial k of a batch is bit
for bit a batch of trial k alone.

:func:`covariance_from_point_errors` predicts, to first order, the scatter of the
parameters caused by errors in the 3D points themselves.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from calib.camera import TsaiCamera
from calib.camera_batch import TsaiCameras, project_tsai_jacobian_batch
from calib.checks import check_image_size
from calib.rotation import EULER_SEQ, right_jacobian_batch, rotvec2matrix_batch
from calib.tsai import FULL_MIN_POINTS, N_TSAI, TSAI_PARAMETERS, _kappa_scale, _pack

INVALID_PX = 1e6  # the residual of a point that does not project (as calib.tsai)
ROTATION_STEP = 1e-6  # rad: central-difference step of Euler angles against the rotvec
_LAMBDA_START = 1e-6  # the damping of the column-scaled normal equations at the start
_LAMBDA_STALL = 1e10  # a trial whose damping grows past this makes no progress: it stops
# Below this reciprocal condition of the column-scaled J^T J (1e-7 for 7 points of the
# paper's cameras) the rounding of J^T J (~1e-16 of its largest eigenvalue) reaches 1e-4
# of the smallest: the data do not determine some parameters, the covariance is NaN.
RCOND_MIN = 1e-12
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
        """The T calibrated cameras (for :mod:`calib.metrics_batch`)."""
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
        start = _pack(start)
    q0 = np.asarray(start, dtype=float)
    if q0.shape not in ((N_TSAI,), (n_t, N_TSAI)):
        raise ValueError(f"start must be a TsaiCamera or have shape ({n_t}, 11), got {q0.shape}")
    if not np.isfinite(q0).all():
        raise ValueError("the start parameters must be finite")
    return np.array(np.broadcast_to(q0, (n_t, N_TSAI)))


def _residuals_and_jacobian(
    q: NDArray[np.float64],
    points: NDArray[np.float64],
    pixels: NDArray[np.float64],
    kscale: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Reprojection residuals (T, 2N), px, and their Jacobian (T, 2N, 11) at q (T, 11).

    As ``calib.tsai``: a point that does not project gets the pixel 1e6, and the NaN in its
    rows of the Jacobian become 0.
    """
    rot = rotvec2matrix_batch(q[:, 5:8])
    uv, jac = project_tsai_jacobian_batch(
        points,
        q[:, 0],
        q[:, 1],
        q[:, 2],
        q[:, 3],
        q[:, 4] / kscale,
        rot,
        q[:, 8:11],
        right_jacobian_batch(q[:, 5:8]),
    )
    n_t = len(q)
    uv = uv.reshape(n_t, -1)
    jac = jac.reshape(n_t, -1, N_TSAI)
    jac[:, :, 4] /= kscale
    bad = ~np.isfinite(uv)
    if bad.any():
        uv = np.where(bad, INVALID_PX, uv)
        jac[bad] = np.nan_to_num(jac[bad], nan=0.0)
    return uv - pixels.reshape(n_t, -1), jac


def _solve(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Solve a stack of systems (..., P, P) x = (..., P, K); NaN where a matrix is singular."""
    try:
        return np.linalg.solve(a, b)
    except np.linalg.LinAlgError:
        out = np.full(np.broadcast_shapes(a.shape[:-2], b.shape[:-2]) + b.shape[-2:], np.nan)
        a_b, b_b = np.broadcast_to(a, out.shape[:-2] + a.shape[-2:]), np.broadcast_to(b, out.shape)
        for i in np.ndindex(out.shape[:-2]):
            with contextlib.suppress(np.linalg.LinAlgError):
                out[i] = np.linalg.solve(a_b[i], b_b[i])
        return out


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
    y = _solve(systems, np.broadcast_to((g / d)[:, None, :, None], (*systems.shape[:3], 1)))
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
    res_new, jac_new = _residuals_and_jacobian(q_new, fit.points, fit.pixels, kscale)
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
    res, jac = _residuals_and_jacobian(q0, points, pixels, kscale)
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


def _unit_covariance(normal: NDArray[np.float64]) -> NDArray[np.float64]:
    """(J^T J)^-1 of a stack (T, P, P), inverted with its columns scaled to unit norm; NaN
    where the scaled matrix is singular: its reciprocal condition below ``RCOND_MIN``."""
    d = np.sqrt(np.diagonal(normal, axis1=1, axis2=2))
    d = np.where(d > 0.0, d, 1.0)
    dd = d[:, :, None] * d[:, None, :]
    scaled = normal / dd
    eig = np.linalg.eigvalsh(scaled)
    regular = eig[:, 0] > RCOND_MIN * eig[:, -1]
    inv = _solve(scaled, np.broadcast_to(np.eye(normal.shape[1]), normal.shape)) / dd
    return np.where(regular[:, None, None], inv, np.nan)


def _euler(rotvecs: NDArray[np.float64]) -> NDArray[np.float64]:
    """(T, 3) rotation vectors -> (T, 3) Tsai angles (rx, ry, rz), rad."""
    return Rotation.from_matrix(rotvec2matrix_batch(rotvecs)).as_euler(EULER_SEQ)


def _reporting_jacobian(q: NDArray[np.float64], kscale: float) -> NDArray[np.float64]:
    """(T, 11, 11) derivative of the reported parameters against the internal ones.

    The identity but for kappa1 (1 / kscale) and the angles, whose derivative against the
    rotation vector is taken by central differences as ``calib.tsai`` does.
    """
    n_t = len(q)
    jac = np.broadcast_to(np.eye(N_TSAI), (n_t, N_TSAI, N_TSAI)).copy()
    jac[:, 4, 4] = 1.0 / kscale
    for i in range(3):
        step = np.zeros(3)
        step[i] = ROTATION_STEP
        diff = _euler(q[:, 5:8] + step) - _euler(q[:, 5:8] - step)
        jac[:, 5:8, 5 + i] = np.angle(np.exp(1j * diff)) / (2.0 * ROTATION_STEP)
    return jac


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
    kscale = _kappa_scale(size)
    dof = 2 * n - N_TSAI
    if block < 1:
        raise ValueError(f"block must be at least 1, got {block}")
    blocks = [slice(i, i + block) for i in range(0, n_t, block)]
    fit = (kscale, max_iterations, xtol, min_sigma_px)
    sol = _Solution.concatenate([_levenberg_marquardt(q0[b], p3[b], uv[b], *fit) for b in blocks])
    q = sol.q
    sigma2 = sol.cost / dof
    cov_q = sigma2[:, None, None] * _unit_covariance(sol.normal)
    g = _reporting_jacobian(q, kscale)
    rot = rotvec2matrix_batch(q[:, 5:8])
    euler = Rotation.from_matrix(rot).as_euler(EULER_SEQ)
    values = np.concatenate([q[:, :4], q[:, 4:5] / kscale, euler, q[:, 8:11]], axis=1)
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


def _internal(cameras: TsaiCameras, kscale: float) -> NDArray[np.float64]:
    """T cameras -> (T, 11) internal parameters (as ``calib.tsai._pack``)."""
    rotvecs = Rotation.from_matrix(cameras.world2cam_r).as_rotvec()
    intrinsics = [cameras.f, cameras.cx, cameras.cy, cameras.sx, cameras.kappa1 * kscale]
    return np.concatenate([np.stack(intrinsics, axis=1), rotvecs, cameras.position], axis=1)


def _gain(
    cams: TsaiCameras, p3: NDArray[np.float64], kscale: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """H = (J^T J)^-1 J^T K (T, 11, 3N) of the internal parameters, and (J^T J)^-1."""
    n_t, n = p3.shape[:2]
    q = _internal(cams, kscale)
    _, jac = _residuals_and_jacobian(q, p3, np.zeros((n_t, n, 2)), kscale)
    a, _ = _normal_equations(jac, np.zeros(jac.shape[:2]))
    inv_a = _unit_covariance(a)
    blocks = jac.reshape(n_t, n, 2, N_TSAI)
    jtk = np.einsum("tnka,tnkb->tanb", blocks, blocks[..., 8:11]).reshape(n_t, N_TSAI, 3 * n)
    return inv_a @ jtk, inv_a


def position_covariance_from_blocks(
    cameras: TsaiCameras,
    points: ArrayLike,
    blocks: ArrayLike,
    columns: ArrayLike | None = None,
    shared: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Covariance of T calibrated optical centres from errors of their points, where the
    points' joint covariance is block-diagonal (the LEDs of one stop share a block), plus
    errors that several blocks share.

    The position part of :func:`covariance_from_point_errors` without forming the joint
    matrix: ``sum_s H_s B_s H_s^T`` over the blocks, plus ``(H S)(H S)^T``.

    Args:
        cameras: T cameras (where the derivative is taken: the calibrated ones).
        points: (T, n, 3) each calibration's world points, m.
        blocks: (T, S, k, k) the blocks of the points' joint covariance, m^2, in the
            order x0, y0, z0, x1, ... of a layout of S k / 3 points.
        columns: (T, 3n) where each point coordinate sits in that layout (default: the
            first 3n, in order; a trial that lost points keeps the layout of the rest).
        shared: (S k, M) or (T, S k, M) the layout's errors per unit of an (M,) standard
            normal vector common to the blocks (a marker's surveying error, the same at
            every stop of a child), m; adds ``S S^T`` to the joint covariance. None: none.

    Returns:
        (T, 3, 3) covariance of the optical centres, m^2.
    """
    p3 = np.ascontiguousarray(np.asarray(points, dtype=float))
    b = np.asarray(blocks, dtype=float)
    n_t, n = p3.shape[:2]
    if p3.shape != (len(cameras), n, 3) or b.ndim != 4 or b.shape[0] != n_t:
        raise ValueError(
            f"points must be ({len(cameras)}, n, 3) and blocks ({len(cameras)}, S, k, k), "
            f"got {p3.shape} and {b.shape}"
        )
    n_blocks, k = b.shape[1:3]
    cols = np.broadcast_to(np.arange(3 * n) if columns is None else columns, (n_t, 3 * n))
    if n_blocks * k < 3 * n or cols.max(initial=0) >= n_blocks * k:
        raise ValueError(f"{n_blocks} blocks of {k} rows cannot hold {n} points")
    h, _ = _gain(cameras, p3, _kappa_scale(cameras.image_size))
    full = np.zeros((n_t, 3, n_blocks * k))
    full[np.arange(n_t)[:, None, None], np.arange(3)[None, :, None], cols[:, None, :]] = h[:, 8:11]
    hs = full.reshape(n_t, 3, n_blocks, k)
    cov = np.einsum("tasj,tbsj->tab", np.einsum("tasi,tsij->tasj", hs, b), hs)
    if shared is None:
        return cov
    loads = np.asarray(shared, dtype=float)
    if loads.shape[-2] != n_blocks * k or loads.ndim not in (2, 3):
        raise ValueError(f"shared must be ({n_blocks * k}, M) or (T, ..., M), got {loads.shape}")
    effect = full @ loads  # (T, 3, M)
    return cov + effect @ np.swapaxes(effect, 1, 2)


def covariance_from_point_errors(
    cameras: TsaiCamera | TsaiCameras,
    points: ArrayLike,
    points_covariance: ArrayLike,
    *,
    sigma_px: float | ArrayLike = 0.0,
) -> NDArray[np.float64]:
    """First-order covariance of Tsai's parameters caused by errors in the 3D points.

    What it is for: the analytic prediction of a Monte-Carlo visit. The LED points of one
    robot stop are placed with the measured pose of the robot's marker, so they share its
    error: their joint covariance has blocks off the diagonal, and the error they cause
    does not average down over the points as independent errors would. A calibration on
    points P + dP (and exact pixels) moves its parameters by

        dq = (J^T J)^-1 J^T K dP,  K = -d uv / d P (the -R rows of the pixel Jacobian)

    to first order, so their covariance is H Sigma_P H^T with H = (J^T J)^-1 J^T K. With
    ``sigma_px`` the independent pixel noise adds sigma_px^2 (J^T J)^-1 (the bound of
    :func:`calib.tsai.predicted_covariance`). Both are evaluated at ``cameras`` (the true
    camera, or the noise-free calibration of the visit).

    Args:
        cameras: one camera, or T cameras (one per trial).
        points: (N, 3) world points, m; or (T, N, 3) with T cameras.
        points_covariance: (3N, 3N) joint covariance of the points, m^2, rows in the order
            x0, y0, z0, x1, ...; or (T, 3N, 3N).
        sigma_px: standard deviation of the pixel noise, px (a float or (T,)).

    Returns:
        (11, 11) covariance of the reported parameters in the order of ``TSAI_PARAMETERS``
        (SI units; x, y, z the optical centre, m); (T, 11, 11) for T cameras.
    """
    one = isinstance(cameras, TsaiCamera)
    cams = TsaiCameras.from_cameras([cameras]) if one else cameras
    n_t = len(cams)
    p3 = np.asarray(points, dtype=float)
    if p3.shape[-1:] != (3,) or p3.ndim not in ((2,) if one else (2, 3)):
        raise ValueError(f"points must have shape (N, 3) or ({n_t}, N, 3), got {p3.shape}")
    p3 = np.ascontiguousarray(np.broadcast_to(p3, (n_t, *p3.shape[-2:])))
    n = p3.shape[1]
    cov_p = np.asarray(points_covariance, dtype=float)
    if cov_p.shape not in ((3 * n, 3 * n), (n_t, 3 * n, 3 * n)):
        raise ValueError(f"points_covariance must have shape ({3 * n}, {3 * n}), got {cov_p.shape}")
    kscale = _kappa_scale(cams.image_size)
    q = _internal(cams, kscale)
    h, inv_a = _gain(cams, p3, kscale)
    sigma2 = np.broadcast_to(np.asarray(sigma_px, dtype=float) ** 2, (n_t,))
    cov_q = h @ cov_p @ np.swapaxes(h, 1, 2) + sigma2[:, None, None] * inv_a
    g = _reporting_jacobian(q, kscale)
    cov = g @ cov_q @ np.swapaxes(g, 1, 2)
    return cov[0] if one else cov
