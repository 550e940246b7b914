"""One simulated total-station shot: tilt reading, automatic aim, noise, levelling, rounding.

The simulation (MuJoCo or the pure-numpy leapfrog) gives the true prism positions in the
instrument frame I (fixed to the possibly tilted instrument) and the true tilt; this module
returns what the real instrument would report, or a typed failure.

Order of operations, as in the instrument: read the inclinometer (refuse beyond its working
range); point at the predicted position; lock by automatic aim; measure the polar
coordinates in I with noise; level them with the (noisy) tilt reading; round to the output
resolution. Random draws happen in that order (tilt reading, then measurement noise).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.instruments.aim import LineOfSight, auto_aim
from twin.instruments.noise import normalise_polar, polar_sigmas, quantise_polar
from twin.instruments.polar import (
    TotalStationMeasurement,
    cartesian2polar,
    polar2cartesian,
)
from twin.instruments.tilt import (
    TiltReading,
    level_points,
    read_inclinometer,
)
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec


@dataclass(frozen=True)
class SimulatedShot:
    """A simulated shot: the instrument's report and, from the simulation's truth, which
    prism it actually locked onto (a real instrument cannot know this).

    Attributes:
        measurement: the levelled, rounded measurement.
        prism_index: row of the prism array the automatic aim locked onto.
    """

    measurement: TotalStationMeasurement
    prism_index: int


def levelled_shots(
    points_instrument: ArrayLike,
    readings: ArrayLike,
    spec: TotalStationSpec,
    normals: ArrayLike,
) -> NDArray[np.float64]:
    """Shots at known prisms from given noise: measure in I, level, round.

    Args:
        points_instrument: (..., 3) true prism positions in the instrument frame, m.
        readings: (..., 2) the (roll, pitch) readings that level each shot, rad.
        spec: instrument specification.
        normals: (..., 3) standard normal draws of each shot's (d, hz, v) noise.

    Returns:
        (..., 3) levelled, rounded polar triplets (d, hz, v).
    """
    polar = cartesian2polar(np.asarray(points_instrument, dtype=float))
    noisy = normalise_polar(polar + polar_sigmas(polar, spec) * normals)
    r = np.asarray(readings, dtype=float)
    levelled = level_points(polar2cartesian(noisy), r[..., 0], r[..., 1])
    return quantise_polar(cartesian2polar(levelled), spec)


def shots_from_normals(
    points_instrument: ArrayLike,
    true_tilt: ArrayLike,
    spec: TotalStationSpec,
    inclinometer: InclinometerSpec,
    normals: ArrayLike,
    tilt_normals: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`measure_points` with its noise given: the caller draws it, in its own order.

    Args:
        points_instrument: (..., 3) true prism positions in the instrument frame, m.
        true_tilt: (..., 2) the true (roll, pitch), rad.
        spec, inclinometer: instrument and inclination-sensor specifications.
        normals: (..., 3) standard normal draws of the polar noise.
        tilt_normals: (..., 2) standard normal draws of the inclination readings.

    Returns:
        ``(polar, readings)`` as :func:`measure_points`.
    """
    readings = np.asarray(true_tilt, dtype=float) + inclinometer.sigma * np.asarray(tilt_normals)
    return levelled_shots(points_instrument, readings, spec, normals), readings


def measure_points(
    points_instrument: ArrayLike,
    true_roll: ArrayLike,
    true_pitch: ArrayLike,
    spec: TotalStationSpec,
    inclinometer: InclinometerSpec,
    rng: np.random.Generator,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Vectorised shots at known prisms (no aiming, no range or tilt-range check).

    Args:
        points_instrument: (..., 3) true prism positions in the instrument frame, m.
        true_roll, true_pitch: true tilt, rad, broadcastable to ``points.shape[:-1]``.
        spec, inclinometer: instrument and inclination-sensor specifications.
        rng: random generator.

    Returns:
        ``(polar, readings)``: (..., 3) levelled, rounded polar triplets (d, hz, v) and
        (..., 2) the (roll, pitch) readings, rad, used to level each shot.
    """
    p = np.asarray(points_instrument, dtype=float)
    shape = p.shape[:-1]
    roll = np.broadcast_to(np.asarray(true_roll, float), shape)
    pitch = np.broadcast_to(np.asarray(true_pitch, float), shape)
    tilt_normals = rng.standard_normal((*shape, 2))  # the readings first, as the instrument
    normals = rng.standard_normal(p.shape)
    return shots_from_normals(
        p, np.stack([roll, pitch], -1), spec, inclinometer, normals, tilt_normals
    )


def simulate_shot(
    prisms_instrument: ArrayLike,
    aim_at_level: ArrayLike,
    spec: TotalStationSpec,
    rng: np.random.Generator,
    *,
    true_tilt: tuple[float, float] = (0.0, 0.0),
    inclinometer: InclinometerSpec | None = None,
    line_of_sight: LineOfSight | None = None,
    timestamp: float = 0.0,
    measurement_rng: Callable[[int], np.random.Generator] | None = None,
) -> SimulatedShot:
    """Simulate one shot of the total station at a predicted prism position.

    Args:
        prisms_instrument: (N, 3) true positions of every prism that could answer, in the
            instrument frame I, m.
        aim_at_level: (3,) predicted position of the wanted prism in the levelled frame, m.
        spec: total-station specification.
        rng: random generator.
        true_tilt: true (roll, pitch) of the instrument, rad (see :mod:`.tilt`).
        inclinometer: inclination-sensor specification; None measures without
            compensation (the instrument frame is then assumed level: no tilt reading).
        line_of_sight: visibility callback ``(prism_index, position_I) -> bool``.
        timestamp: time of the shot, s.
        measurement_rng: gives the generator of the measurement noise from the index of
            the prism locked (default ``rng``, which also draws the tilt reading): keyed
            noise, the same for the same prism whatever was drawn before.

    Returns:
        The measurement and the index of the prism actually locked.

    Raises:
        TiltOutOfRangeError, NoPrismInConeError, LineOfSightBlockedError, OutOfRangeError.
    """
    prisms = np.asarray(prisms_instrument, dtype=float)
    aim = np.asarray(aim_at_level, dtype=float)
    if inclinometer is not None:
        reading: TiltReading | None = read_inclinometer(
            true_tilt[0], true_tilt[1], inclinometer, rng, timestamp
        )
        readings = np.array([reading.roll, reading.pitch])
        pointing = reading.instrument2level.T @ aim
    else:
        reading = None
        readings = np.zeros(2)
        pointing = aim
    index = auto_aim(prisms, pointing, spec, line_of_sight)
    noise = rng if measurement_rng is None else measurement_rng(index)
    polar = levelled_shots(prisms[index], readings, spec, noise.standard_normal(3))
    measurement = TotalStationMeasurement.from_polar(polar, float(timestamp), tilt=reading)
    return SimulatedShot(measurement=measurement, prism_index=index)
