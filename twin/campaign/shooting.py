"""Measuring a child's three corner cubes with the total station, with retries.

The instrument is pointed at each cube's predicted position (the parent's pose estimate,
the child's own pose estimate and the marker geometry). A lost lock is retried with a
better aim: corrected by how far the cubes already measured lay from their prediction, or,
with none measured yet, swept around the prediction. Three shots that do not fit the
assembly (a wrong prism) are measured once more.
"""

from __future__ import annotations

import itertools
import math
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from calib.rotation import rot_z, wrap_angle
from twin.hal.devices import TotalStation
from twin.hal.readings import TotalStationMeasurement
from twin.instruments.consistency import DEFAULT_FALSE_ALARM_RATE, chi2_statistic, chi2_threshold
from twin.instruments.errors import (
    DistanceMeasurementError,
    InconsistentMarkerError,
    InstrumentBusyError,
    InstrumentError,
    InstrumentFaultError,
    InstrumentTimeoutError,
    LineOfSightBlockedError,
    NoPrismInConeError,
)
from twin.instruments.marker import MarkerAssembly
from twin.localization.observation import ChildObservation, observe_child
from twin.localization.pose import ParentPose

SWEEP_DEG = (2.0, -2.0, 4.0, -4.0, 6.0, -6.0)
"""Horizontal offsets of the aim tried after a lost lock with nothing to correct it, deg."""

MAX_AIM_CORRECTION = 0.1
"""Largest correction of a cube's predicted position by the cubes already measured, m:
beyond it the earlier shot is taken to have locked another prism (they are 0.3 m apart)."""


class ShotReport(Protocol):
    """Where the shots' failures (a lost lock, a prism missing) and events (a prism aimed at
    again from the others, a search) are reported: ``(kind, message, details)``."""

    def failure(self, kind: str, message: str, details: dict[str, Any]) -> None: ...

    def event(self, kind: str, message: str, details: dict[str, Any]) -> None: ...


RETRIED = (NoPrismInConeError, LineOfSightBlockedError)
"""Failures worth another aim; others (out of range, tilt) are not."""

REPEATED = (InstrumentBusyError, InstrumentTimeoutError, DistanceMeasurementError)
"""Failures of a real instrument, not of the aim (busy, no answer in time, no distance):
the same aim is tried again, within the same number of attempts."""


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


SEARCH_DEG = (8.0, -8.0, 12.0, -12.0, 16.0, -16.0, 22.0, -22.0, 28.0, -28.0, 35.0, -35.0)
"""Horizontal offsets from a child's predicted place searched when no prism answered, deg."""

DISTINCT = 0.02
"""Two shots closer than this, m, locked the same prism."""

SAME_MARKER = 0.15
"""Two children measured closer than this, m, are one marker measured twice: the robots'
bodies keep their masts farther apart."""

MIN_ORIENTING_RANGE = 1.0
"""A child nearer than this, m, is not used to correct the parent's heading: a few
centimetres of the parent's position error would turn its bearing too much."""


def shoot_at(
    station: TotalStation,
    aim: NDArray[np.float64],
    retries: int,
    report: ShotReport,
    k: int,
    failed: list[str] | None = None,
) -> TotalStationMeasurement | None:
    """One shot aimed at ``aim``, retried after a lost lock with aims swept around it.

    ``failed`` (when given) receives the kind of each failure of a real instrument itself
    (an error code of its own, or busy or silent on every attempt) that ended the shot
    without a measurement: a prism search would not help. Failures of the geometry (out of
    range, tilted) are not among them: the search goes on as before.
    """
    sweep = 0
    aimed = True
    for attempt in range(retries + 1):
        point = aim if sweep == 0 else _swept(aim, SWEEP_DEG[(sweep - 1) % len(SWEEP_DEG)])
        try:
            station.point(point)
            return station.measure()
        except RETRIED as exc:
            kind = "lost_lock" if isinstance(exc, NoPrismInConeError) else "line_of_sight"
            report.failure(kind, str(exc), {"cube": k, "attempt": attempt})
            sweep += 1
            aimed = True
        except REPEATED as exc:
            report.failure(exc.reason.value, str(exc), {"cube": k, "attempt": attempt})
            aimed = False
        except InstrumentError as exc:
            report.failure(exc.reason.value, str(exc), {"cube": k, "attempt": attempt})
            if failed is not None and isinstance(exc, InstrumentFaultError):
                failed.append(exc.reason.value)
            return None
    if aimed:
        report.failure("shot_given_up", f"cube {k}: no lock after {retries + 1} aims", {"cube": k})
    else:
        message = f"cube {k}: no measurement after {retries + 1} attempts"
        report.failure("shot_given_up", message, {"cube": k})
        if failed is not None:
            failed.append("shot_given_up")
    return None


SENSE_FROM_ABOVE = 0.5
"""Least share of a cube triangle's area that must show from above for its sense of turn
to label it: a triangle steeper than 60 degrees (an assembly whose cubes stand one above
another) is labelled by its sides alone."""


def _turn_sense(points: NDArray[np.float64]) -> float:
    """The sign of the turn from the first of three points to the second to the third,
    seen from above (+1 counter-clockwise), or 0 where less than
    :data:`SENSE_FROM_ABOVE` of their triangle's area shows from above."""
    normal = np.cross(points[1] - points[0], points[2] - points[0])
    if abs(normal[2]) < SENSE_FROM_ABOVE * np.linalg.norm(normal):
        return 0.0
    return float(np.sign(normal[2]))


def _pair_labels(
    points: NDArray[np.float64], cubes_body: NDArray[np.float64]
) -> tuple[tuple[int, ...], float]:
    """The labelling of 2 or 3 measured prisms that best fits the assembly's side lengths
    (the triangle is scalene: its sides tell its corners apart), and the worst misfit, m.

    Three prisms are labelled only in the assembly's own sense of turn, seen from above
    (the child stands upright): a mirrored labelling swaps two sides, which an assembly
    built a few millimetres off its drawing can fit better than the true one where two
    sides differ by little, and its pose would be upside down. A triangle that shows
    little from above (:func:`_turn_sense` 0) is labelled by its sides alone."""
    n = len(points)
    pairs = list(itertools.combinations(range(n), 2))
    measured = {(a, b): np.linalg.norm(points[a] - points[b]) for a, b in pairs}
    k = len(cubes_body)
    body = {
        (i, j): np.linalg.norm(cubes_body[i] - cubes_body[j]) for i in range(k) for j in range(k)
    }
    sense = _turn_sense(points) if n == 3 and _turn_sense(cubes_body) else 0.0
    best: tuple[tuple[int, ...], float] = ((), np.inf)
    for labels in itertools.permutations(range(k), n):
        if sense and _turn_sense(cubes_body[list(labels)]) != sense:
            continue  # mirrored
        misfit = 0.0
        for a, b in pairs:
            misfit = max(misfit, abs(measured[a, b] - body[labels[a], labels[b]]))
        if misfit < best[1]:
            best = (labels, misfit)
    return best


def _third_cube(
    points: NDArray[np.float64], labels: tuple[int, ...], cubes_body: NDArray[np.float64]
) -> tuple[int, NDArray[np.float64]]:
    """The missing cube's label and position (levelled frame) from two identified ones,
    the assembly standing level (a rigid motion in the plane, the height of the others)."""
    (i, j), missing = labels, ({0, 1, 2} - set(labels)).pop()
    b = cubes_body[:, :2]
    vb, vm = b[j] - b[i], points[1, :2] - points[0, :2]
    angle = math.atan2(vm[1], vm[0]) - math.atan2(vb[1], vb[0])
    rot = rot_z(angle)[:2, :2]
    xy = points[0, :2] + rot @ (b[missing] - b[i])
    z = float(np.mean(points[:, 2])) + float(
        cubes_body[missing, 2] - np.mean(cubes_body[[i, j], 2])
    )
    return missing, np.array([xy[0], xy[1], z])


def _turned_onto(
    predicted: NDArray[np.float64], k: int, point: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The (3, 3) prediction turned about the vertical axis through the instrument and
    shifted along the line of sight so that cube ``k`` falls on ``point``."""
    a = math.atan2(point[1], point[0]) - math.atan2(predicted[k, 1], predicted[k, 0])
    turned = predicted @ rot_z(a).T
    return turned + (point - turned[k])


def oriented_on(
    guess: ParentPose, child_world: NDArray[np.float64], measured_level: NDArray[np.float64]
) -> ParentPose:
    """The parent's guessed pose turned about its vertical axis so that a child's bearing,
    predicted from its world position, is the bearing it was measured at.

    A parent that turned in place knows its heading from odometry to a few degrees (a
    skid-steered robot's wheels scrub), which can send the aim at the wrong child; its
    position is known far better. Surveyors orient on the first backsight before aiming at
    the next: so does the campaign.

    Args:
        guess: the parent's pose guess (yaw and translation in W).
        child_world: (3,) the child's reference point in W, m.
        measured_level: (3,) the same point measured in the parent's levelled frame, m.

    Returns:
        The guess with its yaw corrected, or the guess itself when the child is nearer
        than :data:`MIN_ORIENTING_RANGE`.
    """
    predicted = (np.asarray(child_world, float) - guess.translation) @ guess.rotation
    measured = np.asarray(measured_level, float)
    if min(np.hypot(*predicted[:2]), np.hypot(*measured[:2])) < MIN_ORIENTING_RANGE:
        return guess
    turn = math.atan2(predicted[1], predicted[0]) - math.atan2(measured[1], measured[0])
    return ParentPose(float(wrap_angle(guess.yaw + turn)), guess.translation, guess.covariance)


STILL_NOISE_FREE = 1e-6
"""With a noise-free instrument (no consistency test), a child measured this far, m, from
where it was measured before has moved."""


def moved_between(
    before: ChildObservation, after: ChildObservation, false_alarm_rate: float | None
) -> bool:
    """Whether a child moved between two measurements from one standing parent.

    The parent did not move, so its pose error is common to both and cancels: the
    difference of the two reference points has the covariance of the two measurements.
    A robot is taken to have moved when its chi-square on 3 degrees of freedom exceeds the
    quantile at ``false_alarm_rate`` (None: a noise-free instrument, any difference over
    :data:`STILL_NOISE_FREE`).
    """
    difference = after.point_level - before.point_level
    if false_alarm_rate is None:
        return bool(np.linalg.norm(difference) > STILL_NOISE_FREE)
    chi2 = chi2_statistic(difference, before.covariance + after.covariance)
    return not chi2 <= chi2_threshold(3, false_alarm_rate)


def same_marker(a: NDArray[np.float64], b: NDArray[np.float64]) -> bool:
    """Whether two children's measured reference points, (3,) m, are one marker."""
    return bool(np.linalg.norm(np.asarray(a, float)[:2] - np.asarray(b, float)[:2]) < SAME_MARKER)


def shoot_cubes(
    station: TotalStation,
    predicted: NDArray[np.float64],
    retries: int,
    report: ShotReport,
    cubes_body: NDArray[np.float64] | None = None,
) -> list[TotalStationMeasurement] | None:
    """Shots at the three cubes, labelled cube 0, 1, 2, or None when one could not be had.

    Each cube is aimed at its prediction. The automatic aim locks the prism nearest the
    pointing direction, which need not be the one aimed at (the heading of a parent that
    just moved is known to a degree; a prism may be hidden): the shots are labelled by the
    assembly's side lengths, and a prism not yet measured is aimed at from the two that
    are, which is accurate to millimetres.

    Args:
        station: the instrument. predicted: (3, 3) cube predictions, levelled frame, m.
        retries: further aims allowed per cube after a lost lock.
        report: receives each failure and event.
        cubes_body: (3, 3) the assembly's cubes in its body frame (default: labels are
            the aims, as with a perfect prediction).
    """
    shots: list[TotalStationMeasurement] = []

    def add(shot: TotalStationMeasurement | None) -> None:
        if shot is None:
            return
        p = shot.to_cartesian()
        if all(np.linalg.norm(p - s.to_cartesian()) > DISTINCT for s in shots):
            shots.append(shot)

    failed: list[str] = []
    for k in range(len(predicted)):
        add(shoot_at(station, predicted[k], retries, report, k, failed))
    if cubes_body is None:
        return shots if len(shots) == len(predicted) else None
    if not shots and not failed:
        # The child is not where it was thought to be (its odometry drifted): search.
        centre = predicted.mean(axis=0)
        for degrees in SEARCH_DEG:
            report.event("prism_search", f"searching {degrees:+.0f} deg from the prediction", {})
            add(shoot_at(station, _swept(centre, degrees), 0, report, 0))
            if shots:
                break
    for _ in range(3):
        if len(shots) in (0, 3):
            break
        points = np.array([s.to_cartesian() for s in shots])
        if len(shots) == 2:
            # The two prisms' distance tells which two they are, not which is which: try
            # both ways round, the one that puts the third cube nearer its prediction first.
            labels, _misfit = _pair_labels(points, cubes_body)
            tries = [_third_cube(points, labels, cubes_body)]
            tries.append(_third_cube(points, labels[::-1], cubes_body))
            tries.sort(key=lambda t: float(np.linalg.norm(t[1] - predicted[t[0]])))
            for missing, aim in tries:
                report.event("prism_reaimed", f"aiming at cube {missing} from the other two", {})
                add(shoot_at(station, aim, 0, report, missing))
                if len(shots) == 3:
                    break
        else:
            # One prism, which may be any of the three: for each guess, nearest first, turn
            # the prediction about the instrument's vertical axis onto it (the heading of a
            # parent that just moved is the least known) and aim at another cube.
            guesses = np.argsort(np.linalg.norm(predicted - points[0], axis=1))
            for k in guesses:
                turned = _turned_onto(predicted, int(k), points[0])
                report.event("prism_reaimed", f"aiming at the others as if cube {k} was locked", {})
                for j in range(len(predicted)):
                    if j != k and len(shots) < 2:
                        add(shoot_at(station, turned[j], 0, report, j))
                if len(shots) >= 2:
                    break
    if len(shots) != 3:
        report.failure("prism_missing", f"measured {len(shots)} distinct prisms of 3", {})
        return None
    points = np.array([s.to_cartesian() for s in shots])
    labels, _misfit = _pair_labels(points, cubes_body)
    ordered = [shots[labels.index(k)] for k in range(3)]
    return ordered


def measure_child(
    station: TotalStation,
    child: str,
    parent: ParentPose,
    child_pose: NDArray[np.float64],
    marker: MarkerAssembly,
    floor_z: float,
    retries: int,
    report: ShotReport,
    false_alarm_rate: float | None = DEFAULT_FALSE_ALARM_RATE,
) -> ChildObservation | None:
    """The child's observation (reference point, marker pose) from three shots, or None.

    Shots that do not fit the assembly are reported (``inconsistent_marker``) and taken
    once more, aimed by the first try's measurements. ``false_alarm_rate`` is the
    consistency test's (None: no test, for a noise-free instrument).
    """
    predicted = predict_cubes_level(parent, child_pose, marker, floor_z)
    for attempt in range(2):
        shots = shoot_cubes(station, predicted, retries, report, marker.cubes_body)
        if shots is None:
            return None
        try:
            return observe_child(child, shots, station.spec, station.inclinometer, marker=marker)
        except InconsistentMarkerError as exc:
            report.failure("inconsistent_marker", str(exc), {"attempt": attempt})
            measured = np.array([s.to_cartesian() for s in shots])
            shift = np.median(measured - predicted, axis=0)
            if np.linalg.norm(shift) <= MAX_AIM_CORRECTION:
                predicted = predicted + shift
    return None
