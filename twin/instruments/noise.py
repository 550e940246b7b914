"""Noise and output quantisation of the total station, and the covariance they imply.

Distance noise has standard deviation ``const + ppm * 1e-6 * d``; each angle has
``angle_sigma``, and the pointing error on the prism (``pointing_sigma``, m across the line
of sight) adds ``pointing_sigma / (d sin v)`` to the horizontal angle and
``pointing_sigma / d`` to the zenith angle, in quadrature. The instrument rounds its
output to ``distance_resolution`` and ``angle_resolution``; rounding adds a uniform error of
variance ``resolution**2 / 12``, which :func:`polar_covariance` includes by default. All
arrays are (..., 3) polar triplets (d m, hz rad, v rad) in the convention of
:mod:`twin.instruments.polar`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.instruments.polar import TWO_PI, polar2cartesian_jacobian
from twin.instruments.tilt import tilt_covariance
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec

MIN_POINTING_DISTANCE = 0.1
"""Below this distance (m, slope or horizontal) the pointing error's angle is taken at it,
so that a point straight above the instrument does not get an infinite angle error."""


def distance_sigma(distance: ArrayLike, spec: TotalStationSpec) -> NDArray[np.float64]:
    """(...,) slope distances, m -> (...,) distance standard deviations, m."""
    d = np.asarray(distance, dtype=float)
    return spec.distance_sigma_const + spec.distance_sigma_ppm * 1e-6 * d


def polar_sigmas(polar: ArrayLike, spec: TotalStationSpec) -> NDArray[np.float64]:
    """(..., 3) polar triplets -> (..., 3) standard deviations (m, rad, rad) of the noise."""
    p = np.asarray(polar, dtype=float)
    sd = distance_sigma(p[..., 0], spec)
    sa = np.full_like(sd, spec.angle_sigma)
    if spec.pointing_sigma == 0.0:
        return np.stack([sd, sa, sa], axis=-1)
    d = np.maximum(p[..., 0], MIN_POINTING_DISTANCE)
    horizontal = np.maximum(d * np.abs(np.sin(p[..., 2])), MIN_POINTING_DISTANCE)
    s_hz = np.hypot(sa, spec.pointing_sigma / horizontal)
    s_v = np.hypot(sa, spec.pointing_sigma / d)
    return np.stack([sd, s_hz, s_v], axis=-1)


def polar_covariance(
    polar: ArrayLike, spec: TotalStationSpec, *, quantisation: bool = True
) -> NDArray[np.float64]:
    """(..., 3) polar triplets -> (..., 3, 3) diagonal covariance of the reported values.

    With ``quantisation`` the rounding variance ``resolution**2 / 12`` is added.
    """
    var = polar_sigmas(polar, spec) ** 2
    if quantisation:
        var = (
            var
            + np.array([spec.distance_resolution, spec.angle_resolution, spec.angle_resolution])
            ** 2
            / 12.0
        )
    return var[..., :, None] * np.eye(3)


def normalise_polar(polar: ArrayLike) -> NDArray[np.float64]:
    """Bring (..., 3) polar triplets to hz in [0, 2pi), v in [0, pi] (same Cartesian point)."""
    p = np.array(polar, dtype=float)
    d, hz, v = p[..., 0], p[..., 1], np.mod(p[..., 2], TWO_PI)
    over = v > np.pi  # past the nadir/zenith: the same point seen through the other face
    v = np.where(over, TWO_PI - v, v)
    hz = np.where(over, hz + np.pi, hz)
    hz = np.mod(hz, TWO_PI)
    hz = np.where(hz >= TWO_PI, 0.0, hz)
    return np.stack([d, hz, v], axis=-1)


def quantise_polar(polar: ArrayLike, spec: TotalStationSpec) -> NDArray[np.float64]:
    """Round (..., 3) polar triplets to the output resolution, as the instrument displays.

    The distance is a multiple of ``distance_resolution``; each angle a multiple of
    ``angle_resolution`` (hz wrapped to [0, 2pi), v clipped to [0, pi]). A zero resolution
    leaves that value unchanged.
    """
    p = np.array(polar, dtype=float)
    if spec.distance_resolution > 0:
        p[..., 0] = np.round(p[..., 0] / spec.distance_resolution) * spec.distance_resolution
    if spec.angle_resolution > 0:
        res = spec.angle_resolution
        hz = np.round(p[..., 1] / res) * res
        p[..., 1] = np.where(hz >= TWO_PI - 0.5 * res, 0.0, hz)
        v_max = np.floor(np.pi / res) * res
        p[..., 2] = np.clip(np.round(p[..., 2] / res) * res, 0.0, v_max)
    return p


def cartesian_covariance(
    polar: ArrayLike,
    spec: TotalStationSpec,
    inclinometer: InclinometerSpec | None = None,
    *,
    quantisation: bool = True,
) -> NDArray[np.float64]:
    """(..., 3, 3) covariance, m^2, of the Cartesian point of levelled polar measurements.

    Propagates :func:`polar_covariance` through the polar-to-Cartesian Jacobian and, if an
    inclinometer is given, adds the levelling error of :func:`tilt_covariance`. Linearised
    at ``polar`` (pass the measured values: that is what a real system has).
    """
    p = np.asarray(polar, dtype=float)
    jac = polar2cartesian_jacobian(p)
    cov = jac @ polar_covariance(p, spec, quantisation=quantisation) @ np.swapaxes(jac, -1, -2)
    if inclinometer is not None:
        d, hz, v = p[..., 0], p[..., 1], p[..., 2]
        xyz = np.stack([d * np.sin(v) * np.cos(hz), d * np.sin(v) * np.sin(hz), d * np.cos(v)], -1)
        cov = cov + tilt_covariance(xyz, inclinometer)
    return cov
