"""The campaign's abort: the group cannot go on, or a loop of it reached its bound."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


class CampaignAborted(RuntimeError):
    """The group cannot go on (CPS lost both children, or no leg can be planned)."""


NO_PROGRESS = "no_progress"
"""The failure of a loop of the campaign that reached its bound (:mod:`twin.campaign.bounds`)."""


class NoProgress(CampaignAborted):
    """A loop of the campaign reached its bound (:mod:`twin.campaign.bounds`): the campaign
    cannot progress. Made and recorded by :meth:`twin.campaign.drives.Drives.no_progress`.

    Attributes:
        stage: the campaign's stage (``reference``, ``travel``, ``station``, ``return``).
        what: what was counted (legs of a travel, travels, stops of a data set, drives).
        position: (2,) where the parent stands (its CPS estimate), m in W.
        count: how many were taken. bound: the most allowed.
    """

    def __init__(
        self, stage: str, what: str, position: NDArray[np.float64], count: int, bound: int
    ) -> None:
        self.stage, self.what, self.count, self.bound = stage, what, count, bound
        self.position = np.asarray(position, dtype=float).reshape(2).copy()
        x, y = self.position
        super().__init__(
            f"no progress in the {stage} stage, the parent at ({x:.2f}, {y:.2f}) m: {count} "
            f"{what}, the most the scenario allows (campaign.progress_slack)"
        )
