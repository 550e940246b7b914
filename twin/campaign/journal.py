"""The campaign's journal: what it records beside the devices' readings, what it counts,
and what it tells a progress display.

Every record goes to the recorder (the run's log, :mod:`twin.campaign.records`) as it
happens: the stages, the parent's fixes, the data points and sets, the calibrations, the
visits skipped, the failures (something went wrong and the campaign went on) and the
events (something the campaign did that is not a fault).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.campaign.records import (
    CALIBRATION,
    CHILD_PLACED,
    CONTROL_SIGHTING,
    DATASET,
    EVENT,
    FAILURE,
    PARENT_FIX,
    POINT,
    SKIPPED,
    STAGE,
    CalibrationRecord,
    CampaignEvent,
    ChildPlaced,
    ControlSighting,
    DataPoint,
    DataSet,
    Failure,
    ParentFix,
    SkippedVisit,
    Stage,
)
from twin.hal.devices import Clock
from twin.hal.recording import Recorder
from twin.localization.observation import ChildObservation
from twin.localization.pose import ParentPose


@dataclass(frozen=True)
class Progress:
    """What the campaign is doing now, for a progress display.

    Attributes:
        stage: ``reference``, ``travel``, ``station``, ``return`` or ``done``.
        robot: the robot moving ("" if none). camera: the camera concerned ("" if none).
        points: LED points gathered for the current data set.
        calibrated: cameras calibrated so far. detail: words.
    """

    stage: str
    robot: str = ""
    camera: str = ""
    points: int = 0
    calibrated: int = 0
    detail: str = ""


@dataclass
class CampaignOutcome:
    """What the campaign did (its records are in the recorder).

    Attributes:
        calibrations: every calibration, in order. skipped: visits without one.
        failures: count by kind. events: count by kind. travelled: the parent's travel, m.
    """

    calibrations: list[CalibrationRecord] = field(default_factory=list)
    skipped: list[SkippedVisit] = field(default_factory=list)
    failures: Counter = field(default_factory=Counter)
    events: Counter = field(default_factory=Counter)
    travelled: float = 0.0


class Journal:
    """Records, counts and progress of one campaign.

    Args:
        recorder: where the records go. clock: the rig's clock (timestamps).
        progress: called with a :class:`Progress` at each stage, robot and point.
    """

    def __init__(
        self,
        recorder: Recorder,
        clock: Clock,
        progress: Callable[[Progress], None] | None = None,
    ) -> None:
        self.recorder = recorder
        self.clock = clock
        self.progress = progress or (lambda _: None)
        self.outcome = CampaignOutcome()
        self._current = Progress("start")
        self._fixes = 0
        self._last_xy = np.zeros(2)

    def _record(self, topic: str, record: Any) -> None:
        self.recorder.record(topic, record, record.timestamp)

    def failure(self, kind: str, message: str, robot: str = "", camera: str = "", **details):
        """Something went wrong and the campaign goes on: counted and recorded."""
        self.outcome.failures[kind] += 1
        self._record(FAILURE, Failure(self.clock.now(), kind, message, robot, camera, details))

    def event(self, kind: str, message: str, robot: str = "", camera: str = "", **details):
        """Something the campaign did that is not a fault: counted and recorded."""
        self.outcome.events[kind] += 1
        event = CampaignEvent(self.clock.now(), kind, message, robot, camera, details)
        self._record(EVENT, event)

    def stage(self, stage: str, camera: str = "", visit: int = 0, detail: str = "") -> None:
        """A stage starts."""
        self._record(STAGE, Stage(self.clock.now(), stage, camera, visit, detail))
        self._current = Progress(stage, camera=camera, detail=detail)
        self.show()

    @property
    def current(self) -> Progress:
        """What the campaign is doing now (its stage first)."""
        return self._current

    def show(self, **changes: Any) -> None:
        """Tell the progress display what changed (``robot``, ``camera``, ``points``)."""
        self._current = replace(self._current, **changes, calibrated=len(self.outcome.calibrations))
        self.progress(self._current)

    @property
    def travelled(self) -> float:
        """The parent's travel from fix to fix so far, m."""
        return self._distance

    def parent_fix(self, pose: ParentPose, observed: Sequence[ChildObservation] = ()) -> None:
        """The parent's pose after a CPS step (from the children ``observed``), or at its
        first station."""
        if self._fixes == 0:
            self._distance = 0.0
        else:
            self._distance += float(np.linalg.norm(pose.translation[:2] - self._last_xy))
        self._last_xy = pose.translation[:2].copy()
        self._record(
            PARENT_FIX,
            ParentFix(
                self.clock.now(),
                self._fixes,
                pose.yaw,
                pose.translation,
                pose.covariance,
                self._distance,
                tuple(o.child for o in observed),
                np.array([o.point_level for o in observed]).reshape(-1, 3),
                np.array([o.covariance for o in observed]).reshape(-1, 3, 3),
            ),
        )
        self._fixes += 1

    def child_placed(
        self,
        child: str,
        point_level: NDArray[np.float64],
        covariance: NDArray[np.float64],
        world: NDArray[np.float64],
    ) -> None:
        """A child was placed in the CPS state from the standing parent's measurement."""
        self._record(
            CHILD_PLACED, ChildPlaced(self.clock.now(), child, point_level, covariance, world)
        )

    def control_sighting(self, sighting: ControlSighting) -> None:
        """A control point measured from the parent's current station."""
        self._record(CONTROL_SIGHTING, sighting)

    def point(self, point: DataPoint) -> None:
        """A data point of a camera."""
        self._record(POINT, point)

    def dataset(self, dataset: str, camera: str, visit: int, points: int) -> None:
        """A data set is complete."""
        self._record(DATASET, DataSet(self.clock.now(), dataset, camera, visit, points))

    def calibration(self, record: CalibrationRecord) -> None:
        """A camera was calibrated."""
        self.outcome.calibrations.append(record)
        self._record(CALIBRATION, record)
        self.show()

    def skipped(
        self, camera: str, visit: int, station: NDArray[np.float64], reason: str, message: str
    ) -> None:
        """A visit yielded no calibration."""
        s = SkippedVisit(self.clock.now(), camera, visit, station, reason, message)
        self.outcome.skipped.append(s)
        self._record(SKIPPED, s)


class RobotJournal:
    """A journal's failures and events about one robot, as :mod:`.shooting` reports them:
    ``failure(kind, message, details)`` and ``event(kind, message, details)``."""

    def __init__(self, journal: Journal, robot: str, camera: str = "") -> None:
        self.journal, self.robot, self.camera = journal, robot, camera

    def failure(self, kind: str, message: str, details: dict[str, Any]) -> None:
        self.journal.failure(kind, message, self.robot, self.camera, **details)

    def event(self, kind: str, message: str, details: dict[str, Any]) -> None:
        self.journal.event(kind, message, self.robot, self.camera, **details)
