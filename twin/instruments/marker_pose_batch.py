"""Marker poses of many trials at once: :mod:`.marker_pose` as arrays over trials.

Every function takes arrays with leading trial axes ``...`` (usually one axis of T Monte
Carlo trials) and gives, for each trial, what the scalar function of
:mod:`twin.instruments.marker_pose` gives for that trial alone: the same formulas in the
same order, with one small matrix product, SVD or solve per trial. Nothing is reduced
across trials, so a trial's result does not depend on the others in its batch.

The rotation is the Kabsch solution by SVD, as :meth:`scipy.spatial.transform.Rotation.
align_vectors` computes it for the scalar fit: ``B = sum_i (m_i - m_mean)(b_i - b_mean)^T``,
``B = U S V^T``, ``R = U diag(1, 1, det(U V^T)) V^T``, then through a quaternion and back
as scipy does (see :func:`kabsch_rotation`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from calib.rotation import skew
from twin.instruments.consistency import chi2_statistic_batch
from twin.instruments.marker import MarkerAssembly
from twin.instruments.marker_pose import _CENTROID, MARKER_DOF, MarkerPose


def check_cubes_batch(cubes: ArrayLike, name: str = "cubes") -> NDArray[np.float64]:
    """Return measured cubes as a finite (..., 3, 3) array, or raise ValueError."""
    arr = np.asarray(cubes, dtype=float)
    if arr.ndim < 2 or arr.shape[-2:] != (3, 3):
        raise ValueError(
            f"{name} must have shape (..., 3, 3) (trials, three cubes, x y z), got {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or inf")
    return arr


def check_cube_covariance_batch(
    covariance: ArrayLike | None, batch_shape: tuple[int, ...]
) -> NDArray[np.float64]:
    """(..., 3, 3, 3) per-cube or (..., 9, 9) joint cube covariances, m^2 -> (..., 9, 9).

    None gives zeros. Raises ValueError for a wrong shape, NaN or an asymmetric matrix
    (the tolerance of :func:`twin.instruments.marker_pose.check_cube_covariance`).
    """
    if covariance is None:
        return np.zeros((*batch_shape, 9, 9))
    c = np.asarray(covariance, dtype=float)
    if c.shape == (*batch_shape, 3, 3, 3):
        full = np.zeros((*batch_shape, 9, 9))
        for i in range(3):
            full[..., 3 * i : 3 * i + 3, 3 * i : 3 * i + 3] = c[..., i, :, :]
        c = full
    if c.shape != (*batch_shape, 9, 9):
        raise ValueError(
            f"cube covariance must have shape {(*batch_shape, 3, 3, 3)} or "
            f"{(*batch_shape, 9, 9)}, got {c.shape}"
        )
    if not np.all(np.isfinite(c)):
        raise ValueError("cube covariance contains NaN or inf")
    ct = np.swapaxes(c, -1, -2)
    if not (np.abs(c - ct) <= 1e-18 + 1e-9 * np.abs(ct)).all():
        raise ValueError("cube covariance must be symmetric")
    return c


def _symmetrise(cov: NDArray[np.float64]) -> NDArray[np.float64]:
    return 0.5 * (cov + np.swapaxes(cov, -1, -2))


@dataclass(frozen=True, eq=False)
class MarkerPoseBatch:
    """Estimated poses of a marker assembly over trials (see :class:`MarkerPose`).

    Attributes:
        rotation: (..., 3, 3) body2frame rotations.
        translation: (..., 3) body2frame translations, m.
        covariance: (..., 6, 6) covariance of (d_theta rad, d_t m).
        rms_residual: (...,) rms distance between fitted and measured cubes, m.
        chi2: (...,) the residual's chi-square (``dof`` = 3); None without a covariance.
        dof: degrees of freedom of ``chi2``.
    """

    rotation: NDArray[np.float64]
    translation: NDArray[np.float64]
    covariance: NDArray[np.float64]
    rms_residual: NDArray[np.float64]
    chi2: NDArray[np.float64] | None = None
    dof: int = MARKER_DOF

    @property
    def batch_shape(self) -> tuple[int, ...]:
        """The trial axes ``...``."""
        return self.translation.shape[:-1]

    def transform(self, points_body: ArrayLike) -> NDArray[np.float64]:
        """Map (K, 3) body points to ``frame`` in every trial -> (..., K, 3), m."""
        p = np.asarray(points_body, dtype=float)
        return p @ np.swapaxes(self.rotation, -1, -2) + self.translation[..., None, :]

    def point_jacobian(self, points_body: ArrayLike) -> NDArray[np.float64]:
        """(..., K, 3, 6) Jacobian of the mapped points with respect to (d_theta, d_t)."""
        rp = np.asarray(points_body, dtype=float) @ np.swapaxes(self.rotation, -1, -2)
        eye = np.broadcast_to(np.eye(3), (*rp.shape, 3))
        return np.concatenate([-skew(rp), eye], axis=-1)

    def trial(self, index: int | tuple[int, ...]) -> MarkerPose:
        """The pose of one trial as a :class:`MarkerPose`."""
        return MarkerPose(
            rotation=self.rotation[index],
            translation=self.translation[index],
            covariance=self.covariance[index],
            rms_residual=float(self.rms_residual[index]),
            chi2=None if self.chi2 is None else float(self.chi2[index]),
            dof=self.dof,
        )


def kabsch_rotation(
    measured_centred: NDArray[np.float64], body_centred: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(..., 3, 3) rotations R minimising sum |m_i - R b_i|^2 for centred point sets.

    The arithmetic of :meth:`Rotation.align_vectors` (``a`` measured, ``b`` body) for every
    trial: ``B = sum_i m_i b_i^T`` summed in the order of the points, its SVD, the sign
    fix, and the round trip through a quaternion that orthonormalises the result.

    Args:
        measured_centred: (..., P, 3) measured points minus their mean.
        body_centred: (P, 3) body points minus their mean.
    """
    m, b = measured_centred, body_centred
    outer = m[..., 0, :, None] * b[0]
    for i in range(1, b.shape[0]):
        outer = outer + m[..., i, :, None] * b[i]
    u, _, vh = np.linalg.svd(outer)
    flip = np.linalg.det(u @ vh) < 0.0
    u[..., :, -1] = np.where(flip[..., None], -u[..., :, -1], u[..., :, -1])
    r = u @ vh
    return Rotation.from_matrix(r.reshape(-1, 3, 3)).as_matrix().reshape(r.shape)


def fit_marker_pose_batch(
    cubes_measured: ArrayLike,
    marker: MarkerAssembly,
    covariance: ArrayLike | None = None,
) -> MarkerPoseBatch:
    """Rigid poses of the assembly from its three measured cubes, in every trial.

    Args:
        cubes_measured: (..., 3, 3) measured cubes, rows in the order of
            ``marker.cubes_body``, m.
        marker: the assembly geometry.
        covariance: (..., 3, 3, 3) per-cube or (..., 9, 9) joint covariance of the measured
            cubes, m^2; None gives zero pose covariances and no chi-square.

    Returns:
        Per trial what :func:`twin.instruments.marker_pose.fit_marker_pose` returns.
    """
    m = check_cubes_batch(cubes_measured, "cubes_measured")
    shape = m.shape[:-2]
    sigma = check_cube_covariance_batch(covariance, shape)
    b = marker.cubes_body
    b_mean, m_mean = b.mean(axis=0), m.mean(axis=-2)
    r = kabsch_rotation(m - m_mean[..., None, :], b - b_mean)
    rt = np.swapaxes(r, -1, -2)
    t = m_mean - (r @ b_mean[:, None])[..., 0]
    residual = m - (b @ rt + t[..., None, :])
    rms = np.sqrt(np.mean(np.sum(residual**2, axis=-1), axis=-1))
    pose = MarkerPoseBatch(r, t, np.zeros((*shape, 6, 6)), rms)
    jac = pose.point_jacobian(b).reshape(*shape, 9, 6)
    jac_t = np.swapaxes(jac, -1, -2)
    a = np.linalg.solve(jac_t @ jac, jac_t)  # (..., 6, 9)
    cov = _symmetrise(a @ sigma @ np.swapaxes(a, -1, -2))
    chi2 = None
    if covariance is not None:
        # Orthonormal basis of the residual space (left null space of the pose Jacobian).
        basis = np.linalg.svd(jac, full_matrices=True)[0][..., :, 6:]  # (..., 9, 3)
        basis_t = np.swapaxes(basis, -1, -2)
        z = (basis_t @ residual.reshape(*shape, 9, 1))[..., 0]
        # The surveyed geometry's own error (see fit_marker_pose).
        tested = sigma + marker.survey_sigma**2 * np.eye(9)
        chi2 = chi2_statistic_batch(z, basis_t @ tested @ basis)
    return MarkerPoseBatch(r, t, cov, rms, chi2)


def led_positions_batch(
    pose: MarkerPoseBatch, marker: MarkerAssembly
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Positions of the LEDs and their joint covariance in every trial.

    Returns:
        ``(leds, covariance)``: (..., K, 3) LED positions in the pose's frame, m, and their
        (..., 3K, 3K) joint covariance, m^2 (rows x0 y0 z0 x1 ...).
    """
    leds = pose.transform(marker.leds_body)
    shape = pose.batch_shape
    jac = pose.point_jacobian(marker.leds_body).reshape(*shape, -1, 6)
    cov = jac @ pose.covariance @ np.swapaxes(jac, -1, -2)
    return leds, _symmetrise(cov)


def cube_centroid_batch(
    cubes_measured: ArrayLike, covariance: ArrayLike | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The assembly's reference point (mean of the three cubes) and its covariance.

    Args:
        cubes_measured: (..., 3, 3) measured cubes, m.
        covariance: (..., 3, 3, 3) or (..., 9, 9) cube covariance, m^2; None gives zeros.

    Returns:
        ``(point, covariance)``: (..., 3) m and (..., 3, 3) m^2.
    """
    m = check_cubes_batch(cubes_measured, "cubes_measured")
    sigma = check_cube_covariance_batch(covariance, m.shape[:-2])
    return m.mean(axis=-2), _CENTROID @ sigma @ _CENTROID.T
