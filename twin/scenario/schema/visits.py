"""``[calibration]``: the visits of the calibration plan."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

from twin.scenario.limits import MAX_VISITS, AngleDeg, Point2
from twin.scenario.schema.frozen import Frozen, Name


class CalibrationVisit(Frozen):
    """One calibration of one camera: where the parent stands while the child moves.

    Attributes:
        camera: name of the camera.
        station: (x, y) of the parent's body origin on the floor, m.
        yaw_deg: parent's heading there, degrees.
    """

    camera: Name
    station: Point2
    yaw_deg: AngleDeg = 0.0


class Calibration(Frozen):
    """The calibration plan.

    Attributes:
        visits: the visits in the order they are made (a camera may be visited again), at
            most ``MAX_VISITS``.
        min_visible_fraction: the least fraction of a camera's floor view that the total
            station must see from the visit's station (line of sight to the corner cubes,
            within range), for the station to be accepted.
    """

    visits: tuple[CalibrationVisit, ...] = Field(min_length=1, max_length=MAX_VISITS)
    min_visible_fraction: Annotated[float, Field(gt=0.0, le=1.0)] = 0.5
