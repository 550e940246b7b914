"""Measuring a child's three corner cubes with the total station, with retries.

The instrument is pointed at each cube's predicted position (the parent's pose estimate,
the child's own pose estimate and the marker geometry). A lost lock is retried with a
better aim: corrected by how far the cubes already measured lay from their prediction, or,
with none measured yet, swept around the prediction. Three shots that do not fit the
assembly (a wrong prism) are measured once more.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from twin.hal.devices import TotalStation
from twin.hal.readings import TotalStationMeasurement
from twin.instruments.consistency import DEFAULT_FALSE_ALARM_RATE
from twin.instruments.errors import (
    InconsistentMarkerError,
    InstrumentError,
    LineOfSightBlockedError,
    NoPrismInConeError,
)
from twin.instruments.marker import MarkerAssembly
from twin.localization.observation import ChildObservation, observe_child
from twin.localization.planar import rot_z
from twin.localization.pose import ParentPose

SWEEP_DEG = (2.0, -2.0, 4.0, -4.0, 6.0, -6.0)
"""Horizontal offsets of the aim tried after a lost lock with nothing to correct it, deg."""

MAX_AIM_CORRECTION = 0.1
"""Largest correction of a cube's predicted position by the cubes already measured, m:
beyond it the earlier shot is taken to have locked another prism (they are 0.3 m apart)."""

FailureSink = Callable[[str, str, dict], None]
"""``(kind, message, details)``: where a failure is reported."""

RETRIED = (NoPrismInConeError, LineOfSightBlockedError)
"""Failures worth another aim; others (out of range, tilt) are not."""


def predict_cubes_level(
    parent: ParentPose, child_pose: NDArray[np.float64], marker: MarkerAssembly, floor_z: float
) -> NDArray[np.float64]:
    """(3, 3) predicted cube positions in the parent's levelled frame, m.

    Args:
        parent: the parent's pose estimate. child_pose: (3,) the child's (x, y, yaw) in W.
        marker: the assembly's geometry. floor_z: the floor's height in W, m.
    """
    x, y, yaw = child_pose
    cubes_w = marker.cubes_body @ rot_z(yaw).T + np.array([x, y, floor_z])
    return (cubes_w - parent.translation) @ parent.rotation


def _swept(aim: NDArray[np.float64], degrees: float) -> NDArray[np.float64]:
    return rot_z(math.radians(degrees)) @ aim


def shoot_cubes(
    station: TotalStation,
    predicted: NDArray[np.float64],
    retries: int,
    report: FailureSink,
) -> list[TotalStationMeasurement] | None:
    """Shots at the three predicted cubes, or None when one could not be had.

    Args:
        station: the instrument. predicted: (3, 3) cube predictions, levelled frame, m.
        retries: further aims allowed per cube after a lost lock.
        report: receives each failure.
    """
    shots: list[TotalStationMeasurement] = []
    offsets: list[NDArray[np.float64]] = []
    for k in range(len(predicted)):
        aim = predicted[k].copy()
        if offsets:
            aim = aim + np.mean(offsets, axis=0)
            # A large offset means a wrong prism was locked: do not follow it.
            if np.linalg.norm(aim - predicted[k]) > MAX_AIM_CORRECTION:
                aim = predicted[k].copy()
        shot = None
        for attempt in range(retries + 1):
            if attempt > 0 and not offsets:
                aim = _swept(predicted[k], SWEEP_DEG[(attempt - 1) % len(SWEEP_DEG)])
            station.point(aim)
            try:
                shot = station.measure()
                break
            except RETRIED as exc:
                report(
                    "lost_lock" if isinstance(exc, NoPrismInConeError) else "line_of_sight",
                    str(exc),
                    {"cube": k, "attempt": attempt},
                )
            except InstrumentError as exc:
                report(exc.reason.value, str(exc), {"cube": k, "attempt": attempt})
                return None
        if shot is None:
            report("shot_given_up", f"cube {k}: no lock after {retries + 1} aims", {"cube": k})
            return None
        shots.append(shot)
        offsets.append(shot.to_cartesian() - predicted[k])
    return shots


def measure_child(
    station: TotalStation,
    child: str,
    parent: ParentPose,
    child_pose: NDArray[np.float64],
    marker: MarkerAssembly,
    floor_z: float,
    retries: int,
    report: FailureSink,
    false_alarm_rate: float | None = DEFAULT_FALSE_ALARM_RATE,
) -> ChildObservation | None:
    """The child's observation (reference point, marker pose) from three shots, or None.

    Shots that do not fit the assembly are reported (``inconsistent_marker``) and taken
    once more, aimed by the first try's measurements. ``false_alarm_rate`` is the
    consistency test's (None: no test, for a noise-free instrument).
    """
    predicted = predict_cubes_level(parent, child_pose, marker, floor_z)
    for attempt in range(2):
        shots = shoot_cubes(station, predicted, retries, report)
        if shots is None:
            return None
        try:
            return observe_child(child, shots, station.spec, station.inclinometer, marker=marker)
        except InconsistentMarkerError as exc:
            report("inconsistent_marker", str(exc), {"attempt": attempt})
            measured = np.array([s.to_cartesian() for s in shots])
            shift = np.median(measured - predicted, axis=0)
            if np.linalg.norm(shift) <= MAX_AIM_CORRECTION:
                predicted = predicted + shift
    return None
