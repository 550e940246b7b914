"""Analytic derivatives of Tsai's projection (:mod:`calib.camera`) with respect to its 11
parameters, for one camera or T cameras at once (arrays with leading axes ``...``).

The parameters are (f, cx, cy, sx, kappa1, rotation (3), camera position C (3)); the camera
frame point is ``R @ (X - C)``. The rotation enters through ``drot``, the (3, 3) derivative
of R with respect to the three rotation parameters as used by the caller (the right
Jacobian of SO(3) for a rotation vector): d(R v)/d(rot) = -R skew(v) drot.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from calib.camera import per_point
from calib.distortion import distortion_scale


def project_tsai_jacobian(
    points_world: NDArray[np.float64],
    f: float | NDArray[np.float64],
    cx: float | NDArray[np.float64],
    cy: float | NDArray[np.float64],
    sx: float | NDArray[np.float64],
    kappa1: float | NDArray[np.float64],
    world2cam_r: NDArray[np.float64],
    camera_position: NDArray[np.float64],
    drot: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Pixels and their analytic derivatives with respect to Tsai's parameters, without
    input checks.

    Args:
        points_world: (..., N, 3) points, m: (N, 3) for one camera, (T, N, 3) for T.
        f, cx, cy: px. sx: -. kappa1: 1/px^2. Each a float or of shape (...).
        world2cam_r: (..., 3, 3). camera_position: (..., 3) optical centre in the world, m.
        drot: (..., 3, 3), see the module text.

    Returns:
        pixels (..., N, 2) and the Jacobian (..., N, 2, 11) in the order f, cx, cy, sx,
        kappa1, rot(3), C(3). Points behind their camera give NaN.
    """
    fb, sxb, kb = per_point(f), per_point(sx), per_point(kappa1)
    v = points_world - camera_position[..., None, :]
    pc = v @ np.swapaxes(world2cam_r, -1, -2)
    z = pc[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        zi = np.where(z > 0, 1.0 / z, np.nan)
    xn, yn = pc[..., 0] * zi, pc[..., 1] * zi
    xu, yu = fb * xn, fb * yn
    ru2 = xu * xu + yu * yu
    t = kb * ru2
    r_u = np.sqrt(np.maximum(ru2, 0))
    s = r_u * distortion_scale(kb * (r_u * r_u))  # the distorted radius
    s = np.where(ru2 > 0, s / np.sqrt(np.where(ru2 > 0, ru2, 1.0)), 1.0)
    ds_dt = -(s**3) / (1.0 + 3.0 * t * s * s)
    xd, yd = s * xu, s * yu
    # d(xd, yd) / d(xu, yu)
    g = ds_dt * kb * 2.0
    a11, a12 = s + xu * g * xu, xu * g * yu
    a21, a22 = yu * g * xu, s + yu * g * yu
    jac = np.zeros((*pc.shape[:-1], 2, 11))
    # f: xu = f xn
    dxd_df = a11 * xn + a12 * yn
    dyd_df = a21 * xn + a22 * yn
    jac[..., 0, 0], jac[..., 1, 0] = sxb * dxd_df, dyd_df
    jac[..., 0, 1] = 1.0
    jac[..., 1, 2] = 1.0
    jac[..., 0, 3] = xd
    ds_dk = ds_dt * ru2
    jac[..., 0, 4], jac[..., 1, 4] = sxb * xu * ds_dk, yu * ds_dk
    # d(xn, yn) / d(pc): rows (2, 3) per point
    dn_dpc = np.zeros((*pc.shape[:-1], 2, 3))
    dn_dpc[..., 0, 0] = zi
    dn_dpc[..., 0, 2] = -xn * zi
    dn_dpc[..., 1, 1] = zi
    dn_dpc[..., 1, 2] = -yn * zi
    # d(u, v) / d(xn, yn) = diag(sx, 1) @ A @ f
    a = np.empty((*pc.shape[:-1], 2, 2))
    a[..., 0, 0], a[..., 0, 1] = sxb * (a11 * fb), sxb * (a12 * fb)
    a[..., 1, 0], a[..., 1, 1] = a21 * fb, a22 * fb
    duv_dpc = a @ dn_dpc  # (..., N, 2, 3)
    # pc = R (X - C): d pc / d C = -R ; d pc / d rot = -R skew(v) drot. A product with a
    # matrix shared by the N points is one product of (..., 2N, 3) rows (the same sums).
    lead, n = pc.shape[:-2], pc.shape[-2]

    def times(rows: NDArray[np.float64], m: NDArray[np.float64]) -> NDArray[np.float64]:
        return (rows.reshape(*lead, 2 * n, 3) @ m).reshape(*lead, n, 2, 3)

    duv_dc = times(-duv_dpc, world2cam_r)
    jac[..., 8:11] = duv_dc
    sk = np.zeros((*v.shape, 3))
    sk[..., 0, 1], sk[..., 0, 2] = -v[..., 2], v[..., 1]
    sk[..., 1, 0], sk[..., 1, 2] = v[..., 2], -v[..., 0]
    sk[..., 2, 0], sk[..., 2, 1] = -v[..., 1], v[..., 0]
    jac[..., 5:8] = times(duv_dc @ sk, drot)
    uv = np.stack([sxb * xd + per_point(cx), yd + per_point(cy)], axis=-1)
    return uv, jac
