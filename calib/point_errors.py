"""First-order covariance of Tsai's calibrated parameters caused by errors in the 3D points.

A calibration on points P + dP (and exact pixels) moves its internal parameters
(:mod:`calib.tsai_parameters`) by ``dq = H dP``, ``H = (J^T J)^-1 J^T K`` with J the
Jacobian of the pixels and K = -d uv / d P, to first order. The LED points of one robot
stop are placed with the measured pose of the robot's marker, so they share its error;
:func:`position_covariance_from_blocks` propagates such block-diagonal errors (and errors
shared by several stops) to the optical centres, :func:`covariance_from_point_errors` a
full joint covariance to all the parameters. For one camera or T at once.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.camera import TsaiCamera, TsaiCameras
from calib.covariance import normal_inverse
from calib.tsai_parameters import (
    N_TSAI,
    kappa_scale,
    pack,
    reporting_jacobian,
    residuals_and_jacobian,
)


def _gain(
    cams: TsaiCameras, p3: NDArray[np.float64], kscale: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """H = (J^T J)^-1 J^T K (T, 11, 3N) of the internal parameters, and (J^T J)^-1."""
    n_t, n = p3.shape[:2]
    _, jac = residuals_and_jacobian(pack(cams), p3, np.zeros((n_t, n, 2)), kscale)
    inv_a = normal_inverse(np.swapaxes(jac, 1, 2) @ jac)
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
    h, _ = _gain(cameras, p3, kappa_scale(cameras.image_size))
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
    kscale = kappa_scale(cams.image_size)
    h, inv_a = _gain(cams, p3, kscale)
    sigma2 = np.broadcast_to(np.asarray(sigma_px, dtype=float) ** 2, (n_t,))
    cov_q = h @ cov_p @ np.swapaxes(h, 1, 2) + sigma2[:, None, None] * inv_a
    g = reporting_jacobian(pack(cams), kscale)
    cov = g @ cov_q @ np.swapaxes(g, 1, 2)
    return cov[0] if one else cov
