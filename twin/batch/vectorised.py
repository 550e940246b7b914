"""The campaign's estimators as array code over the trials of a batch.

:class:`Vectorised` computes what :class:`twin.batch.estimators.TrialByTrial` computes with
the batched forms of the campaign's own estimators: the marker fit and the child's
observation (:func:`twin.localization.observation_batch.observe_child_batch`), the CPS state
(:class:`twin.localization.sequence_batch.CpsBatch`), the LED positions
(:func:`twin.instruments.marker_pose_batch.led_positions_batch`). Each trial's numbers are
those of the scalar code (the tests hold them to it); none depends on the other trials of
its batch.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from twin.batch.estimators import CpsStates, Observations, ParentEstimates, TrialByTrial
from twin.instruments.marker_pose_batch import MarkerPoseBatch, led_positions_batch
from twin.localization.observation_batch import ChildObservationBatch, observe_child_batch
from twin.localization.sequence_batch import CpsBatch


class _BatchCps(CpsStates):
    def __init__(self, trials: int, children: Sequence[str], solver: str, rate: float | None):
        self.sequence = CpsBatch(list(children), trials, solver=solver, false_alarm_rate=rate)

    def children_moved(self, child: str, observations: Observations) -> None:
        self.sequence.children_moved([_observation(child, observations)])

    def parent_moved(self, observations: Sequence[tuple[str, Observations]]) -> NDArray[np.bool_]:
        solution = self.sequence.parent_moved([_observation(c, o) for c, o in observations])
        # A trial without a solution (children too close) is lost: its state is NaN and it
        # counts a failure at every later fix.
        return solution.inconsistent | solution.poor_geometry

    @property
    def parent(self) -> ParentEstimates:
        pose = self.sequence.parent
        return ParentEstimates(pose.yaw, pose.translation, pose.covariance)

    def child_position(self, child: str) -> NDArray[np.float64]:
        return self.sequence.child_position(child)[0]


def _observation(child: str, o: Observations) -> ChildObservationBatch:
    return ChildObservationBatch(child, o.point, o.covariance)


class Vectorised(TrialByTrial):
    """The campaign's estimators over all the trials at once (the batch's default)."""

    def observe(self, polar, spec, inclinometer, marker, false_alarm_rate) -> Observations:
        obs = observe_child_batch("child", polar, spec, inclinometer, marker=marker)
        pose = obs.marker_pose
        assert pose is not None
        return Observations(
            obs.point_level,
            obs.covariance,
            pose.rotation,
            pose.translation,
            pose.covariance,
            obs.marker_inconsistent(false_alarm_rate),
        )

    def cps(self, trials, children, solver, false_alarm_rate) -> CpsStates:
        return _BatchCps(trials, children, solver, false_alarm_rate)

    def leds(self, observations, marker):
        pose = MarkerPoseBatch(
            observations.rotation,
            observations.translation,
            observations.pose_covariance,
            np.zeros(len(observations.point)),
            None,
        )
        return led_positions_batch(pose, marker)
