"""What the trials of a batch know after its latest step, as arrays over all of them: the
parent's estimate, the children's, each camera's delivered calibration and its predicted and
true errors.

The environment reads its trial's row; the environment's own vector (:mod:`twin.envs.vector`)
reads the rows of a group's episodes from one computation (:class:`BatchKnowledge` computes
once per step of the batch, however many episodes read it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from twin.batch.execute import BatchRun, transfer_rms

__all__ = ["BatchKnowledge", "Knowledge"]


@dataclass(frozen=True)
class Knowledge:
    """The estimates of T trials and what they deliver for C cameras (the site's, in order).

    Attributes:
        parent_xy: (T, 2) the instrument's centre, m (W). parent_yaw: (T,) rad.
        parent_covariance: (T, 4, 4) of (yaw rad, x m, y m, z m).
        children: (T, N_child, 3) each child's x, y (its CPS position; its own estimate
            before CPS measured it, or where the trial lost its CPS state), m, and its own
            yaw, rad.
        calibrated: (T, C) whether the camera has a calibration.
        predicted: (T, C) the predicted RMS world-frame position error of its delivered
            calibration (of the visits that calibrated it, the one with the lowest), m; 0
            where none.
        calibration: (T, C) the part of it from the calibration itself, m; 0 where none.
        transfer_now: (T, C) the RMS position error the parent's pose would give the camera
            if it were calibrated from here, m.
        position_error: (T, C) the delivered calibration's true position error, m; NaN
            where none.
        parent_error: (T,) the parent's position error at its last fix, m.
        distance: (T,) the parent's travel, m.
    """

    parent_xy: NDArray[np.float64]
    parent_yaw: NDArray[np.float64]
    parent_covariance: NDArray[np.float64]
    children: NDArray[np.float64]
    calibrated: NDArray[np.bool_]
    predicted: NDArray[np.float64]
    calibration: NDArray[np.float64]
    transfer_now: NDArray[np.float64]
    position_error: NDArray[np.float64]
    parent_error: NDArray[np.float64]
    distance: NDArray[np.float64]


def knowledge(
    batch: BatchRun, cameras: tuple[str, ...], positions: NDArray[np.float64]
) -> Knowledge:
    """What ``batch``'s trials know now, for ``cameras`` with (C, 3) nominal ``positions``
    (m, W)."""
    parent = batch.cps.parent
    t, c = batch.trials, len(cameras)
    predicted = np.zeros((t, c))
    calibration = np.zeros((t, c))
    position_error = np.full((t, c), np.nan)
    calibrated = np.zeros((t, c), dtype=bool)
    for j, camera in enumerate(cameras):
        outcomes = [o for (name, _), o in batch.visits.items() if name == camera]
        if not outcomes:
            continue
        # (V, T): a visit that did not calibrate a trial is never its delivered one; of
        # equal predictions the first visit's is (argmin takes the first).
        ok = np.array([o.calibrated for o in outcomes])
        error = np.hypot(
            [o.predicted_transfer for o in outcomes], [o.predicted_calibration for o in outcomes]
        )
        best = np.argmin(np.where(ok, error, np.inf), axis=0)
        rows = np.arange(t)
        calibrated[:, j] = ok[best, rows]
        on = calibrated[:, j]
        predicted[on, j] = error[best, rows][on]
        own = np.array([o.predicted_calibration for o in outcomes])[best, rows]
        calibration[on, j] = own[on]
        true = np.array([o.position_error for o in outcomes])[best, rows]
        position_error[on, j] = true[on]
    transfer_now = np.stack([transfer_rms(parent, p[None]) for p in positions], axis=1)
    children = np.empty((t, len(batch.plan.children), 3))
    for k, child in enumerate(batch.plan.children):
        believed = batch.robots[child].believed
        try:
            placed = batch.cps.child_position(child)[0][:, :2]
        except ValueError:  # not measured yet in any trial
            placed = np.full((t, 2), np.nan)
        # A trial that has not measured it yet (or lost its CPS state): its own estimate.
        children[:, k, :2] = np.where(np.isnan(placed), believed[:, :2], placed)
        children[:, k, 2] = believed[:, 2]
    estimate, truth = batch.last_estimate, batch.last_truth
    assert estimate is not None
    return Knowledge(
        parent_xy=parent.translation[:, :2].copy(),
        parent_yaw=np.asarray(parent.yaw, dtype=float).copy(),
        parent_covariance=parent.covariance.copy(),
        children=children,
        calibrated=calibrated,
        predicted=predicted,
        calibration=calibration,
        transfer_now=transfer_now,
        position_error=position_error,
        parent_error=np.linalg.norm(estimate.translation - truth, axis=1),
        distance=batch.distance.copy(),
    )


class BatchKnowledge:
    """The :class:`Knowledge` of a batch, computed again only after the batch executed a
    step (:attr:`twin.batch.execute.BatchRun.executed`).

    Args:
        batch: the trials. cameras: the site's cameras' names, in order.
        positions: (C, 3) their nominal positions, m (W).
    """

    def __init__(
        self, batch: BatchRun, cameras: tuple[str, ...], positions: NDArray[np.float64]
    ) -> None:
        self.batch = batch
        self.cameras = cameras
        self.positions = np.asarray(positions, dtype=float).reshape(len(cameras), 3)
        self._known: Knowledge | None = None
        self._at = -1

    def now(self) -> Knowledge:
        """What the trials know after the batch's latest step."""
        if self._known is None or self._at != self.batch.executed:
            self._known = knowledge(self.batch, self.cameras, self.positions)
            self._at = self.batch.executed
        return self._known
