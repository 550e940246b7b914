"""Pose of a marker assembly from its three measured corner cubes, and its LED positions.

The pose is the rigid transform ``body2frame`` (rotation R, translation t) that best maps
the assembly's cube positions onto the measured ones in the least-squares sense (Kabsch /
Umeyama without scale, via :meth:`scipy.spatial.transform.Rotation.align_vectors`).
``frame`` is whatever frame the cubes were measured in (levelled instrument or world).

Covariances are first order. A pose perturbation is (d_theta, d_t), 6 values: a small
rotation vector applied on the left (``R -> exp([d_theta]x) R``, rad, in ``frame``) and a
translation (m). The fit is unweighted, so its covariance is the sandwich
``A Sigma A^T`` with ``A = (J^T J)^-1 J^T`` and ``Sigma`` the (9, 9) cube covariance.

Consistency: three cubes give 9 coordinates for 6 pose parameters; the 3 redundant ones
are the triangle's shape. The fit residual lies, to first order, in the 3-dimensional
complement of the pose Jacobian's range; projected onto it with its covariance it gives a
chi-square statistic with 3 degrees of freedom (:attr:`MarkerPose.chi2`). A wrong prism
lock or a child that moved between shots deforms the measured triangle and makes it large
(the assembly is scalene, so no relabelling of the cubes fits; see
:mod:`twin.instruments.marker`). :func:`marker_consistency_chi2` computes the same
statistic, to first order, from the three side lengths, vectorised.

Every fit is computed once, over arrays with leading trial axes ``...`` (none for one fit,
usually one axis of T Monte Carlo trials): the ``*_batch`` functions, with one small matrix
product, SVD or solve per trial and nothing reduced across trials, so a trial's result does
not depend on the others in its batch. The functions of one fit check their input as one
fit and call them with no trial axes. The rotation is the Kabsch solution by SVD, as
:meth:`scipy.spatial.transform.Rotation.align_vectors` computes it
(:func:`kabsch_rotation`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from calib.rotation import skew
from twin.instruments.consistency import NUMERICAL_FLOOR, chi2_statistic_batch
from twin.instruments.marker import MarkerAssembly

MARKER_DOF = 3
"""Redundancy of a marker pose fitted to three cubes: 9 coordinates - 6 pose parameters."""

_SIDES = ((0, 1), (1, 2), (2, 0))

_CENTROID = np.tile(np.eye(3), 3) / 3.0
"""(3, 9) the mean of three cubes as a linear map of their coordinates."""
_CENTROID.setflags(write=False)


def check_cubes_batch(cubes: ArrayLike, name: str = "cubes") -> NDArray[np.float64]:
    """Return measured cubes as a finite (..., 3, 3) array, or raise ValueError."""
    arr = np.asarray(cubes, dtype=float)
    if arr.ndim < 2 or arr.shape[-2:] != (3, 3):
        raise ValueError(
            f"{name} must have shape (..., 3, 3) (trials, three cubes, x y z), got {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        values = f": {arr.tolist()}" if arr.ndim == 2 else ""
        raise ValueError(f"{name} contains NaN or inf{values}")
    return arr


def check_cubes(cubes: ArrayLike, name: str = "cubes") -> NDArray[np.float64]:
    """Return measured cube positions as a finite (3, 3) array, or raise ValueError."""
    arr = np.asarray(cubes, dtype=float)
    if arr.shape != (3, 3):
        raise ValueError(f"{name} must have shape (3, 3) (three cubes, x y z), got {arr.shape}")
    return check_cubes_batch(arr, name)


def check_cube_covariance_batch(
    covariance: ArrayLike | None, batch_shape: tuple[int, ...]
) -> NDArray[np.float64]:
    """(..., 3, 3, 3) per-cube or (..., 9, 9) joint cube covariances, m^2 -> (..., 9, 9),
    ``...`` the trial axes ``batch_shape``.

    None gives zeros. Raises ValueError for a wrong shape, NaN or an asymmetric matrix.
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
    # np.allclose(c, c.T, rtol=1e-9, atol=1e-18) for finite values, without its overhead.
    if not (np.abs(c - ct) <= 1e-18 + 1e-9 * np.abs(ct)).all():
        raise ValueError("cube covariance must be symmetric")
    return c


def _symmetrise(cov: NDArray[np.float64]) -> NDArray[np.float64]:
    return 0.5 * (cov + np.swapaxes(cov, -1, -2))


@dataclass(frozen=True, eq=False)
class MarkerPose:
    """Estimated pose of a marker assembly, of one fit or over trials (axes ``...``).

    Attributes:
        rotation: (..., 3, 3) body2frame rotation.
        translation: (..., 3) body2frame translation (the body origin in ``frame``), m.
        covariance: (..., 6, 6) covariance of (d_theta rad, d_t m), see the module text.
        rms_residual: root-mean-square distance between the fitted and measured cubes, m
            (a float for one fit, (...,) over trials). Millimetres are noise; centimetres
            mean a wrong prism or a wrong assembly.
        chi2: the residual's chi-square statistic with its covariance (``dof`` = 3
            degrees of freedom, mean 3 for consistent data), as ``rms_residual``; None
            without a covariance.
        dof: degrees of freedom of ``chi2``.
    """

    rotation: NDArray[np.float64]
    translation: NDArray[np.float64]
    covariance: NDArray[np.float64]
    rms_residual: float | NDArray[np.float64]
    chi2: float | NDArray[np.float64] | None = None
    dof: int = MARKER_DOF

    @property
    def batch_shape(self) -> tuple[int, ...]:
        """The trial axes ``...`` (empty for one fit)."""
        return self.translation.shape[:-1]

    def transform(self, points_body: ArrayLike) -> NDArray[np.float64]:
        """Map (K, 3) body points to ``frame`` -> (..., K, 3), m."""
        p = np.asarray(points_body, dtype=float)
        return p @ np.swapaxes(self.rotation, -1, -2) + self.translation[..., None, :]

    def point_jacobian(self, points_body: ArrayLike) -> NDArray[np.float64]:
        """(..., K, 3, 6) Jacobian of the mapped points with respect to (d_theta, d_t)."""
        rp = np.asarray(points_body, dtype=float) @ np.swapaxes(self.rotation, -1, -2)
        eye = np.broadcast_to(np.eye(3), (*rp.shape, 3))
        return np.concatenate([-skew(rp), eye], axis=-1)

    def trial(self, index: int | tuple[int, ...]) -> MarkerPose:
        """The pose of one trial, as one fit."""
        return MarkerPose(
            rotation=self.rotation[index],
            translation=self.translation[index],
            covariance=self.covariance[index],
            rms_residual=float(self.rms_residual[index]),  # type: ignore[index]
            chi2=None if self.chi2 is None else float(self.chi2[index]),  # type: ignore[index]
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
) -> MarkerPose:
    """Rigid poses of the assembly from its three measured cubes, in every trial.

    Args:
        cubes_measured: (..., 3, 3) measured cubes, rows in the order of
            ``marker.cubes_body``, m.
        marker: the assembly geometry.
        covariance: (..., 3, 3, 3) per-cube or (..., 9, 9) joint covariance of the measured
            cubes, m^2; None gives zero pose covariances and no chi-square.

    Returns:
        Per trial what :func:`fit_marker_pose` returns.
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
    pose = MarkerPose(r, t, np.zeros((*shape, 6, 6)), rms)
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
        # The surveyed geometry's own error leaves a residual too (it is a fixed error of
        # each child, not noise of the shots: the pose covariance leaves it out).
        tested = sigma + marker.survey_sigma**2 * np.eye(9)
        chi2 = chi2_statistic_batch(z, basis_t @ tested @ basis)
    return MarkerPose(r, t, cov, rms, chi2)


def fit_marker_pose(
    cubes_measured: ArrayLike,
    marker: MarkerAssembly,
    covariance: ArrayLike | None = None,
) -> MarkerPose:
    """Rigid pose of the assembly from its three measured cubes.

    Args:
        cubes_measured: (3, 3) measured cube positions, rows in the order of
            ``marker.cubes_body``, m.
        marker: the assembly geometry.
        covariance: (3, 3, 3) per-cube or (9, 9) joint covariance of the measured cubes,
            m^2; None gives a zero pose covariance.

    Returns:
        The pose, its (6, 6) covariance and, with a covariance, the residual's chi-square
        (see the module text). The caller decides what chi2 is too large
        (:func:`twin.instruments.consistency.raise_if_inconsistent`).
    """
    m = check_cubes(cubes_measured, "cubes_measured")
    return fit_marker_pose_batch(m, marker, covariance).trial(())


def marker_consistency_chi2(
    cubes_measured: ArrayLike, cube_covariances: ArrayLike, marker: MarkerAssembly
) -> NDArray[np.float64]:
    """Vectorised chi-square (3 dof) of measured cubes against the assembly's triangle.

    Compares the three measured side lengths with the assembly's; to first order this is
    the same statistic as :attr:`MarkerPose.chi2` of :func:`fit_marker_pose`.

    Args:
        cubes_measured: (..., 3, 3) measured cubes in the order of ``marker.cubes_body``, m.
        cube_covariances: (..., 3, 3, 3) covariance of each cube (shots independent), m^2.
        marker: the assembly geometry.

    Returns:
        (...,) chi-square values.
    """
    m = np.asarray(cubes_measured, dtype=float)
    cov = np.asarray(cube_covariances, dtype=float) + marker.survey_sigma**2 * np.eye(3)
    b = marker.cubes_body
    diff = np.stack([m[..., i, :] - m[..., j, :] for i, j in _SIDES], axis=-2)  # (..., 3, 3)
    length = np.linalg.norm(diff, axis=-1)
    body = np.array([np.linalg.norm(b[i] - b[j]) for i, j in _SIDES])
    e = length - body
    u = diff / np.maximum(length, NUMERICAL_FLOOR)[..., None]  # coincident cubes: u = 0
    jac = np.zeros((*m.shape[:-2], 3, 3, 3))  # (..., side, cube, xyz)
    for k, (i, j) in enumerate(_SIDES):
        jac[..., k, i, :] = u[..., k, :]
        jac[..., k, j, :] = -u[..., k, :]
    cov_e = np.einsum("...kci,...cij,...lcj->...kl", jac, cov, jac)
    cov_e = cov_e + NUMERICAL_FLOOR**2 * np.eye(3)
    return np.einsum("...k,...k->...", e, np.linalg.solve(cov_e, e[..., None])[..., 0])


def led_positions_batch(
    pose: MarkerPose, marker: MarkerAssembly
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


def led_positions(
    pose: MarkerPose, marker: MarkerAssembly
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Positions of the LEDs and their joint covariance.

    Returns:
        ``(leds, covariance)``: (N_led, 3) LED positions in the pose's frame, m, and their
        (3 N_led, 3 N_led) joint covariance, m^2 (rows x0 y0 z0 x1 ...).
    """
    return led_positions_batch(pose, marker)


def survey_covariance(marker: MarkerAssembly) -> NDArray[np.float64]:
    """(3 N_led, 3 N_led) covariance of the LEDs' placement error in the child's body
    frame from the assembly's surveying error, m^2 (rows x0 y0 z0 x1 ...).

    Every coordinate of the assembly's cubes (``dc``) and LEDs (``dl``) is off the drawing
    by an error of standard deviation ``marker.survey_sigma``, fixed for the child. A pose
    fitted to the cubes as built then takes the drawing's cubes onto them, off by
    ``A dc`` in the body frame (``A = (J^T J)^-1 J^T``, J the pose Jacobian at the cubes);
    the LEDs placed with it are off by ``P A dc - dl`` (P the pose Jacobian at the LEDs),
    whatever the child's pose: ``sigma^2 (P A A^T P^T + I)``. The error is the same at
    every stop of the child (turned with its heading), so it does not average down over a
    data set's stops (:func:`survey_loading`).
    """
    identity = MarkerPose(np.eye(3), np.zeros(3), np.zeros((6, 6)), 0.0)
    jac = identity.point_jacobian(marker.cubes_body).reshape(-1, 6)
    gain = identity.point_jacobian(marker.leds_body).reshape(-1, 6) @ np.linalg.solve(
        jac.T @ jac, jac.T
    )
    return marker.survey_sigma**2 * (gain @ gain.T + np.eye(len(gain)))


def survey_loading(marker: MarkerAssembly, body2world: ArrayLike) -> NDArray[np.float64]:
    """(..., 3 N_led, 3 N_led) where the LEDs truly stand off where a stop placed them, in
    W, m, per unit of a standard normal vector z shared by every stop of the child (the
    LEDs stand at their placement + ``L z``): ``kron(I, R) C`` with
    ``C C^T`` the :func:`survey_covariance` and R the marker's (..., 3, 3) ``body2world``
    rotation at the stop. Zeros for an assembly known exactly (``survey_sigma`` 0).

    The LEDs of two stops s and t of one child have the joint covariance
    ``L_s L_t^T``.
    """
    rotation = np.asarray(body2world, dtype=float)
    n = len(marker.leds_body)
    if marker.survey_sigma == 0.0:
        return np.zeros((*rotation.shape[:-2], 3 * n, 3 * n))
    factor = np.linalg.cholesky(survey_covariance(marker)).reshape(n, 3, 3 * n)
    turned = np.einsum("...ij,njm->...nim", rotation, factor)
    return turned.reshape(*rotation.shape[:-2], 3 * n, 3 * n)


def survey_layout(
    children: Sequence[str], loadings: Sequence[NDArray[np.float64]], k: int
) -> NDArray[np.float64] | None:
    """The loadings of a data set's S stops on their children's surveying errors
    (:func:`survey_loading`, each (..., r_s, M) with r_s <= ``k`` rows: the stop's LEDs) in
    a layout of one block of ``k`` rows a stop, each stop's rows at the start of its block:
    (..., S k, C M) for the C children (the argument ``shared`` of
    :func:`calib.point_errors.position_covariance_from_blocks`); None where no stop has one
    (an empty loading: an assembly known exactly).
    """
    if not any(load.size for load in loadings):
        return None
    given = [(c, load) for c, load in zip(children, loadings, strict=True) if load.size]
    names = sorted({c for c, _ in given})
    lead, m = given[0][1].shape[:-2], max(load.shape[-1] for _, load in given)
    out = np.zeros((*lead, len(loadings) * k, len(names) * m))
    for s, (child, load) in enumerate(zip(children, loadings, strict=True)):
        if load.size:
            c = names.index(child)
            rows = load.shape[-2]
            out[..., s * k : s * k + rows, c * m : c * m + load.shape[-1]] = load
    return out


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
