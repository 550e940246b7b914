"""Polar measurements of the total station: the record, conversions and their Jacobian.

Convention (written once, used everywhere):

- slope distance ``d`` (m) from the instrument centre to the prism;
- horizontal angle ``hz`` (rad) in the instrument's x-y plane, counter-clockwise from the
  instrument x-axis seen from above (``atan2(y, x)``), reported in [0, 2*pi);
- zenith angle ``v`` (rad): 0 straight up, pi/2 horizontal, reported in [0, pi].

So ``x = d sin(v) cos(hz)``, ``y = d sin(v) sin(hz)``, ``z = d cos(v)``. A real instrument
counts its horizontal circle clockwise; a hardware driver converts with ``hz = -hz_cw``.

Polar triplets are stored in arrays of shape (..., 3) in the order (d, hz, v).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.instruments.arrays import matrices
from twin.instruments.tilt import TiltReading

TWO_PI = 2.0 * np.pi


def _as_triplets(values: ArrayLike, name: str) -> NDArray[np.float64]:
    arr = np.asarray(values, dtype=float)
    if arr.shape[-1:] != (3,):
        raise ValueError(f"{name} must have shape (..., 3), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or inf: {arr}")
    return arr


def polar2cartesian(polar: ArrayLike) -> NDArray[np.float64]:
    """(..., 3) polar (d m, hz rad, v rad) -> (..., 3) Cartesian points in the same frame, m."""
    p = _as_triplets(polar, "polar")
    d, hz, v = p[..., 0], p[..., 1], p[..., 2]
    sv = np.sin(v)
    out = np.empty(p.shape)
    out[..., 0] = d * sv * np.cos(hz)
    out[..., 1] = d * sv * np.sin(hz)
    out[..., 2] = d * np.cos(v)
    return out


def cartesian2polar(points: ArrayLike) -> NDArray[np.float64]:
    """(..., 3) Cartesian points, m -> (..., 3) polar (d m, hz in [0, 2pi), v in [0, pi]).

    Raises ValueError for a point at the instrument centre (direction undefined).
    """
    p = _as_triplets(points, "points")
    d = np.linalg.norm(p, axis=-1)
    if np.any(d == 0.0):
        raise ValueError("points contain the instrument centre (0, 0, 0); no direction defined")
    hz = np.mod(np.arctan2(p[..., 1], p[..., 0]), TWO_PI)
    hz = np.where(hz >= TWO_PI, 0.0, hz)
    out = np.empty(p.shape)
    out[..., 0] = d
    out[..., 1] = hz
    out[..., 2] = np.arctan2(np.hypot(p[..., 0], p[..., 1]), p[..., 2])
    return out


def polar2cartesian_jacobian(polar: ArrayLike) -> NDArray[np.float64]:
    """Jacobian d(x, y, z) / d(d, hz, v) at (..., 3) polar triplets -> (..., 3, 3).

    Rows are x, y, z (m); columns are d (m), hz (rad), v (rad).
    """
    p = _as_triplets(polar, "polar")
    d, hz, v = p[..., 0], p[..., 1], p[..., 2]
    sh, ch, sv, cv = np.sin(hz), np.cos(hz), np.sin(v), np.cos(v)
    rows = [
        [sv * ch, -d * sv * sh, d * cv * ch],
        [sv * sh, d * sv * ch, d * cv * sh],
        [cv, 0.0, -d * sv],
    ]
    return matrices(rows, d.shape)


@dataclass(frozen=True)
class TotalStationMeasurement:
    """What the total station reports for one prism: levelled polar coordinates.

    Attributes:
        timestamp: time of the shot, s.
        distance: slope distance, m.
        horizontal: horizontal angle, rad in [0, 2pi), counter-clockwise from the x-axis of
            the levelled instrument frame.
        zenith: zenith angle, rad in [0, pi].
        tilt: the inclination reading used to level the shot; None if the shot was not
            compensated (the instrument frame is then taken as level).
    """

    timestamp: float
    distance: float
    horizontal: float
    zenith: float
    tilt: TiltReading | None = None

    def __post_init__(self) -> None:
        values = (self.timestamp, self.distance, self.horizontal, self.zenith)
        if not all(np.isfinite(values)):
            raise ValueError(f"measurement values must be finite, got {values}")
        if self.distance <= 0.0:
            raise ValueError(f"distance must be positive, got {self.distance} m")
        if not 0.0 <= self.horizontal < TWO_PI:
            raise ValueError(f"horizontal angle must lie in [0, 2pi), got {self.horizontal} rad")
        if not 0.0 <= self.zenith <= np.pi:
            raise ValueError(f"zenith angle must lie in [0, pi], got {self.zenith} rad")

    @property
    def polar(self) -> NDArray[np.float64]:
        """(3,) polar triplet (d m, hz rad, v rad)."""
        return np.array([self.distance, self.horizontal, self.zenith])

    def to_cartesian(self) -> NDArray[np.float64]:
        """(3,) prism position in the levelled instrument frame, m."""
        return polar2cartesian(self.polar)

    @classmethod
    def from_polar(
        cls, polar: ArrayLike, timestamp: float, tilt: TiltReading | None = None
    ) -> TotalStationMeasurement:
        """Build a record from a (3,) polar triplet."""
        d, hz, v = (float(x) for x in _as_triplets(polar, "polar").reshape(3))
        return cls(timestamp=timestamp, distance=d, horizontal=hz, zenith=v, tilt=tilt)
