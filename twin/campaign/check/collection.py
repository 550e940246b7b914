"""A camera's check data: taken as for a calibration (:mod:`twin.campaign.collection`), but
nothing is calibrated: the check compares the data with the calibrated model."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from twin.campaign.collection import DataCollection
from twin.campaign.strategy import StopPlan


class CheckCollection(DataCollection):
    """:class:`DataCollection` whose visits take the data and calibrate nothing (the data
    points go to the journal as they come, as in a calibration)."""

    def calibrate(
        self, camera: str, visit: int, station: NDArray[np.float64], plan: StopPlan
    ) -> None:
        """Take a visit's data for ``camera`` at the plan's stops."""
        self.collect(camera, "visit", visit, self.settings.station_points, plan)
