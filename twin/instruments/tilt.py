"""Two-axis tilt compensation of the total station on the parent robot.

The instrument frame I is fixed to the (possibly tilted) instrument. The levelled frame L
has its z-axis vertical and its x-axis along the horizontal projection of I's x-axis. The
inclination reading is (roll, pitch), rad, such that

    R_instrument2level = Ry(pitch) @ Rx(roll)

(roll about I's x-axis first, then pitch about the horizontal y-axis). With this choice the
x-axis of I projects exactly onto the x-axis of L, so levelling never changes the heading.
A point measured in I is levelled by ``p_L = R_instrument2level @ p_I``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from twin.instruments.arrays import matrices
from twin.instruments.errors import TiltOutOfRangeError
from twin.instruments.total_station import ARCSEC, InclinometerSpec


@dataclass(frozen=True)
class TiltReading:
    """One reading of the two-axis inclination sensor.

    Attributes:
        timestamp: time of the reading, s.
        roll: inclination about the instrument x-axis, rad.
        pitch: inclination about the horizontal y-axis, rad.
    """

    timestamp: float
    roll: float
    pitch: float

    def __post_init__(self) -> None:
        if not all(np.isfinite((self.timestamp, self.roll, self.pitch))):
            raise ValueError(
                f"tilt reading must be finite, got roll={self.roll}, pitch={self.pitch}, "
                f"timestamp={self.timestamp}"
            )

    @property
    def instrument2level(self) -> NDArray[np.float64]:
        """(3, 3) rotation levelling points of the instrument frame."""
        return tilt_rotation(self.roll, self.pitch)


def tilt_rotation(roll: ArrayLike, pitch: ArrayLike) -> NDArray[np.float64]:
    """R_instrument2level = Ry(pitch) @ Rx(roll) for (...,) angles in rad -> (..., 3, 3)."""
    roll, pitch = np.broadcast_arrays(np.asarray(roll, float), np.asarray(pitch, float))
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    rows = [[cp, sp * sr, sp * cr], [0.0, cr, -sr], [-sp, cp * sr, cp * cr]]
    return matrices(rows, roll.shape)


def tilt_from_orientation(instrument2world: ArrayLike) -> tuple[float, float]:
    """(roll, pitch), rad, of an instrument whose (3, 3) rotation to a z-up frame is given.

    Decomposes ``instrument2world = Rz(yaw) @ Ry(pitch) @ Rx(roll)``; the simulation uses
    this to turn a body orientation into the true inclination.
    """
    r = np.asarray(instrument2world, dtype=float)
    if r.shape != (3, 3) or not np.all(np.isfinite(r)):
        raise ValueError(f"instrument2world must be a finite (3, 3) rotation, got shape {r.shape}")
    _, pitch, roll = Rotation.from_matrix(r).as_euler("ZYX")
    return float(roll), float(pitch)


def check_tilt(reading: TiltReading, spec: InclinometerSpec) -> None:
    """Raise :class:`TiltOutOfRangeError` if either axis exceeds the working range."""
    worst = max(abs(reading.roll), abs(reading.pitch))
    if worst > spec.working_range:
        raise TiltOutOfRangeError(
            f'instrument tilted by roll={reading.roll / ARCSEC:.1f}", '
            f'pitch={reading.pitch / ARCSEC:.1f}"; the compensator accepts at most '
            f'+/-{spec.working_range / ARCSEC:.1f}" on each axis',
            roll=reading.roll,
            pitch=reading.pitch,
            working_range=spec.working_range,
        )


def sample_tilt_readings(
    true_roll: ArrayLike,
    true_pitch: ArrayLike,
    spec: InclinometerSpec,
    rng: np.random.Generator,
) -> NDArray[np.float64]:
    """Noisy inclination readings for (...,) true tilts, rad -> (..., 2) (roll, pitch), rad.

    Vectorised core of :func:`read_inclinometer`; does not check the working range.
    """
    true = np.stack(
        np.broadcast_arrays(np.asarray(true_roll, float), np.asarray(true_pitch, float)), -1
    )
    return true + spec.sigma * rng.standard_normal(true.shape)


def read_inclinometer(
    true_roll: float,
    true_pitch: float,
    spec: InclinometerSpec,
    rng: np.random.Generator,
    timestamp: float = 0.0,
) -> TiltReading:
    """Simulate one inclination reading (noise ``spec.sigma`` on each axis).

    Raises :class:`TiltOutOfRangeError` when the reading lies beyond the working range: the
    instrument refuses to measure rather than report an uncompensated number.
    """
    if not np.isfinite(true_roll) or not np.isfinite(true_pitch):
        raise ValueError(f"true tilt must be finite, got roll={true_roll}, pitch={true_pitch}")
    roll, pitch = sample_tilt_readings(true_roll, true_pitch, spec, rng)
    reading = TiltReading(timestamp=float(timestamp), roll=float(roll), pitch=float(pitch))
    check_tilt(reading, spec)
    return reading


def level_points(points_instrument: ArrayLike, roll: ArrayLike, pitch: ArrayLike) -> NDArray:
    """Level (..., 3) points of the instrument frame with (...,) tilt angles -> (..., 3), m."""
    p = np.asarray(points_instrument, dtype=float)
    r = tilt_rotation(roll, pitch)
    return np.einsum("...ij,...j->...i", r, p)


def tilt_covariance(points_level: ArrayLike, spec: InclinometerSpec) -> NDArray[np.float64]:
    """Covariance (..., 3, 3), m^2, that the inclination noise adds to levelled points.

    A small levelling error (d_roll, d_pitch) moves a point p by ``d_theta x p`` with
    ``d_theta = (d_roll, d_pitch, 0)`` to first order.
    """
    p = np.asarray(points_level, dtype=float)
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    # d_theta x p = G @ (d_roll, d_pitch) with G the first two columns of -[p]_x.
    g = matrices([[0.0, z], [-z, 0.0], [y, -x]], x.shape)
    return spec.sigma**2 * np.einsum("...ik,...jk->...ij", g, g)
