"""The closed-form stages of Tsai's non-coplanar calibration.

Stage 1, radial alignment: with the image centre guessed, the direction of each image point
from the centre is parallel to the direction of its 3D point from the optical axis whatever
f and kappa1 are. That gives a linear system in 7 unknowns (Tsai's sx r1/Ty, sx r2/Ty,
sx r3/Ty, sx Tx/Ty, r4/Ty, r5/Ty, r6/Ty), solved here in its homogeneous form (8 unknowns
up to scale) so that Ty near zero does no harm: the rotation, Tx, Ty and sx.

Stage 2: with the rotation known, f and Tz follow from a linear least-squares fit (no
distortion), then f, Tz and kappa1 from a small nonlinear fit in the undistorted domain.

Reference: R. Y. Tsai, "A versatile camera calibration technique for high-accuracy 3D
machine vision metrology using off-the-shelf TV cameras and lenses", IEEE J. Robotics and
Automation 3(4), 1987.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from calib.checks import check_correspondences, check_min_points, check_spread
from calib.rotation import nearest_rotation

LINEAR_MIN_POINTS = 7  # the radial-alignment system has 7 unknowns


@dataclass(frozen=True)
class RadialAlignment:
    """Result of stage 1.

    Attributes:
        world2cam_r: (3, 3) rotation. tx, ty: first two components of the translation, m.
        sx: horizontal scale factor. condition: condition number of the linear system.
    """

    world2cam_r: NDArray[np.float64]
    tx: float
    ty: float
    sx: float
    condition: float


@dataclass(frozen=True)
class TsaiInitialEstimate:
    """All 11 parameters after the closed-form stages and the (f, Tz, kappa1) fit."""

    f: float
    cx: float
    cy: float
    sx: float
    kappa1: float
    world2cam_r: NDArray[np.float64]
    world2cam_t: NDArray[np.float64]
    condition: float


def radial_alignment(
    points_3d: NDArray[np.float64],
    pixels: NDArray[np.float64],
    cx: float,
    cy: float,
    *,
    check: bool = True,
) -> RadialAlignment:
    """Stage 1 of Tsai's method: rotation, Tx, Ty and sx from the radial alignment constraint.

    Args:
        points_3d: (N, 3) non-coplanar world points, N >= 7, m.
        pixels: (N, 2) observed (distorted) pixels.
        cx, cy: the image centre assumed for this stage, px.
        check: validate the inputs (callers that already did may skip it).

    Returns:
        The rotation (3, 3), Tx and Ty (m), sx, and the condition number of the system.
    """
    p3, uv = check_correspondences(points_3d, pixels)
    if check:
        check_min_points(
            len(p3), LINEAR_MIN_POINTS, "Tsai's linear radial-alignment stage (7 unknowns)"
        )
        check_spread(p3, need_3d=True, what="Tsai's non-coplanar calibration")
    xd = uv[:, 0] - cx  # = sx * x_d
    yd = uv[:, 1] - cy
    # Homogeneous form: yd (sx r1.X + sx Tx) - xd (r2.X + Ty) = 0 in the 8 unknowns
    # v = (sx r1, sx Tx, r2, Ty), solved as the null vector of the system by SVD. Tsai's
    # original divides by Ty, which fails when the world origin lies near the camera's
    # y_c = 0 plane; this form has no such singularity. From 8 points on, the thin SVD
    # gives the whole (8, 8) V in memory linear in N (the full one would also build an
    # (N, N) U: 80 GB at 100k points); 7 points need the full one for V's last row.
    a = np.column_stack([yd[:, None] * p3, yd, -xd[:, None] * p3, -xd])
    scale = np.linalg.norm(a, axis=0)
    scale[scale == 0] = 1.0
    _, sv, vt = np.linalg.svd(a / scale, full_matrices=len(a) < a.shape[1])
    # Consistent data leave one singular value at ~0; the next one measures how well the
    # points pin the solution down.
    condition = float(sv[0] / sv[-2]) if sv[-2] > 0 else float("inf")
    if not np.isfinite(condition) or condition > 1e12:
        raise ValueError(
            "Tsai's radial-alignment system is singular "
            f"(condition number {condition:.3g}); the points do not constrain the camera: "
            "spread them over the image and in depth"
        )
    v = vt[-1] / scale
    v = v / np.linalg.norm(v[4:7])  # r2 is a unit row of the rotation
    sx = float(np.linalg.norm(v[0:3]))

    # v is known up to sign: choose it so that the farthest image point and its 3D point lie
    # on the same side of the optical axis.
    far = int(np.argmax(xd**2 + yd**2))
    for sign in (1.0, -1.0):
        r1, tx = sign * v[0:3] / sx, sign * v[3] / sx
        r2, ty = sign * v[4:7], sign * v[7]
        xc = r1 @ p3[far] + tx
        yc = r2 @ p3[far] + ty
        if np.sign(xc) == np.sign(xd[far]) and np.sign(yc) == np.sign(yd[far]):
            break
    r = nearest_rotation(np.vstack([r1, r2, np.cross(r1, r2)]))
    return RadialAlignment(r, float(tx), float(ty), float(sx), condition)


def _focal_and_tz(
    p3: NDArray[np.float64], yd: NDArray[np.float64], r: NDArray[np.float64], ty: float
) -> tuple[float, float]:
    """Linear least squares for f and Tz, ignoring distortion: f*y_c - yd*Tz = yd*w."""
    yc = p3 @ r[1] + ty
    w = p3 @ r[2]
    a = np.column_stack([yc, -yd])
    (f, tz), *_ = np.linalg.lstsq(a, yd * w, rcond=None)
    return float(f), float(tz)


def tsai_initial_estimate(
    points_3d: NDArray[np.float64],
    pixels: NDArray[np.float64],
    image_size: tuple[int, int],
    centre: tuple[float, float] | None = None,
    *,
    check: bool = True,
) -> TsaiInitialEstimate:
    """Tsai's closed-form stages followed by the (f, Tz, kappa1) fit.

    Args:
        points_3d: (N, 3) non-coplanar world points, N >= 7, m.
        pixels: (N, 2) observed pixels.
        image_size: (width, height), px.
        centre: image centre to assume, px; default the geometric centre of the image.
        check: validate the inputs (callers that already did may skip it).

    Returns:
        An estimate of all 11 parameters, good enough to start the full optimisation.
    """
    p3_world, uv = check_correspondences(points_3d, pixels)
    w, h = image_size
    cx, cy = centre if centre is not None else ((w - 1) / 2.0, (h - 1) / 2.0)
    # Work about the centroid of the points: a camera far from the world origin otherwise
    # makes the linear systems ill-conditioned (coordinates of 40 m spread over 5 m).
    centroid = p3_world.mean(axis=0)
    p3 = p3_world - centroid
    ra = radial_alignment(p3, uv, cx, cy, check=check)
    yd = uv[:, 1] - cy
    r = ra.world2cam_r
    f, tz = _focal_and_tz(p3, yd, r, ra.ty)
    if f < 0:
        # The radial alignment fixes rows 1-2 of R only up to a joint sign with the third
        # row's handedness; f < 0 means the camera was placed behind the points.
        r = np.diag([-1.0, -1.0, 1.0]) @ r
        tx, ty = -ra.tx, -ra.ty
        f, tz = _focal_and_tz(p3, yd, r, ty)
    else:
        tx, ty = ra.tx, ra.ty
    if f <= 0:
        raise ValueError(
            f"Tsai's stage 2 found a non-positive focal length ({f:.4g} px): "
            "the points and pixels are inconsistent (wrong correspondences or units?)"
        )

    # Nonlinear fit of f, Tz and kappa1 (Tsai's third step). The residual is taken in the
    # distorted image, x_d - x_u / (1 + kappa1 r_d^2) with r_d from the observations: in
    # the undistorted domain the cost can shrink towards f -> 0 with kappa1 cancelling the
    # scale, a degenerate solution that this form does not have.
    xd = (uv[:, 0] - cx) / ra.sx
    r2d = xd**2 + yd**2
    xc = p3 @ r[0] + tx
    yc = p3 @ r[1] + ty
    wz = p3 @ r[2]
    r_ref2 = (w / 2.0) ** 2 + (h / 2.0) ** 2

    def residual(q: NDArray[np.float64]) -> NDArray[np.float64]:
        f_, tz_, k_scaled = q
        gain = f_ / ((wz + tz_) * (1.0 + k_scaled / r_ref2 * r2d))
        return np.concatenate([xd - gain * xc, yd - gain * yc])

    fit = least_squares(residual, [f, tz, 0.0], method="lm", xtol=1e-12, ftol=1e-12)
    f, tz, k_scaled = fit.x
    if not (f > 0 and np.isfinite(fit.x).all()):
        raise ValueError(
            f"Tsai's (f, Tz, kappa1) stage found no valid focal length (f = {f:.4g} px): "
            "either the points and pixels are inconsistent (wrong pairing, units or image "
            "size?) or the geometry does not determine the camera (linear-stage condition "
            f"number {ra.condition:.3g})"
        )
    t = np.array([tx, ty, tz]) - r @ centroid
    return TsaiInitialEstimate(
        float(f), float(cx), float(cy), ra.sx, float(k_scaled / r_ref2), r, t, ra.condition
    )
