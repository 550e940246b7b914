"""The CPS sequence in T trials at once: :class:`.sequence.CpsSequence` over arrays.

The trials share the children, the solver and the order of the steps; each has its own
measurements, state ``x`` (T, 4 + 3N) = (parent yaw, x, y, z, child_1 xyz, ...) and joint
covariance ``P`` (T, 4 + 3N, 4 + 3N). A step updates every trial as the scalar sequence
updates its one: the same linear map ``x' = A x + B noise``, ``P' = A P A^T + B Cov B^T``
with each trial's own ``A`` and ``B``, so trial i of a batch is :class:`CpsSequence` run
on trial i's data (to rounding), and does not depend on the other trials.

What the scalar sequence raises for one trial's data, the batch flags and goes on:

- the children do not fit their world positions (:class:`InconsistentChildrenError`): the
  scalar sequence leaves its state unchanged for the caller to measure again; a batch
  cannot measure one trial again, so it keeps every trial's solution and returns the flags
  (:attr:`CpsSolutionBatch.inconsistent`) for the caller to count;
- a horizontal baseline below ``min_baseline`` (ValueError): the trial has no solution;
  it is lost (:attr:`CpsBatch.lost`), its whole state and covariance are NaN from then on
  and every later parent step flags it again as poor geometry.

The batch keeps no step record (at T trials it would be T times the scalar one); each
parent step returns its :class:`CpsSolutionBatch`.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from calib.rotation import rot_z, rot_z_derivative
from twin.instruments.consistency import DEFAULT_FALSE_ALARM_RATE, check_false_alarm_rate
from twin.localization.closed_form_batch import solve_closed_form_batch
from twin.localization.input_checks import DEFAULT_MAX_YAW_STD, DEFAULT_MIN_BASELINE
from twin.localization.input_checks_batch import block_diagonal
from twin.localization.observation_batch import ChildObservationBatch
from twin.localization.pose import ParentPose
from twin.localization.pose_batch import CpsSolutionBatch, ParentPoseBatch
from twin.localization.sequence import (
    add_creep,
    check_children_and_solver,
    check_creep,
    check_step_children,
    child_index,
)
from twin.localization.wls_batch import solve_wls_batch


def _transpose(a: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.swapaxes(a, -1, -2)


class CpsBatch:
    """Joint estimates of a parent and its children along a CPS run, in T trials.

    Args:
        children: the children's names, in state order (the same in every trial).
        n_trials: number of trials T.
        initial_pose: the parent's pose at its first station: one :class:`ParentPose` for
            every trial, a :class:`ParentPoseBatch` of T poses, or None for the world
            origin with zero covariance.
        solver: ``"wls"`` (any number >= 2 of children) or ``"closed_form"`` (exactly two).
        min_baseline, max_yaw_std: passed to the solver (see :mod:`.input_checks`).
        false_alarm_rate: passed to the solver: probability that consistent data are
            flagged inconsistent at a parent step; None switches the test off.
        child_creep: as :class:`twin.localization.sequence.CpsSequence`'s, m.
    """

    def __init__(
        self,
        children: Sequence[str],
        n_trials: int,
        initial_pose: ParentPose | ParentPoseBatch | None = None,
        *,
        solver: str = "wls",
        min_baseline: float = DEFAULT_MIN_BASELINE,
        max_yaw_std: float = DEFAULT_MAX_YAW_STD,
        false_alarm_rate: float | None = DEFAULT_FALSE_ALARM_RATE,
        child_creep: float = 0.0,
    ) -> None:
        names = check_children_and_solver(children, solver)
        if n_trials < 1:
            raise ValueError(f"n_trials must be at least 1, got {n_trials}")
        if initial_pose is None:
            initial_pose = ParentPose(0.0, np.zeros(3))
        if isinstance(initial_pose, ParentPose):
            initial_pose = ParentPoseBatch.repeat(initial_pose, n_trials)
        if initial_pose.n_trials != n_trials:
            raise ValueError(
                f"initial_pose has {initial_pose.n_trials} trials, the batch {n_trials}"
            )
        self._children = names
        self._index = {name: i for i, name in enumerate(names)}
        self._solver = solver
        self._min_baseline = min_baseline
        self._max_yaw_std = max_yaw_std
        self._false_alarm_rate = check_false_alarm_rate(false_alarm_rate)
        self._creep = check_creep(child_creep)
        n = 4 + 3 * len(names)
        self._state = np.full((n_trials, n), np.nan)
        self._state[:, :4] = initial_pose.vector
        self._covariance = np.zeros((n_trials, n, n))
        self._covariance[:, :4, :4] = initial_pose.covariance
        self._known = np.zeros(len(names), dtype=bool)
        self._time = initial_pose.timestamp
        self._n_steps = 0

    # -- read access ---------------------------------------------------------------------
    @property
    def children(self) -> tuple[str, ...]:
        """The children's names in state order."""
        return self._children

    @property
    def solver(self) -> str:
        """The CPS solver used for parent steps."""
        return self._solver

    @property
    def n_trials(self) -> int:
        """Number of trials T."""
        return self._state.shape[0]

    @property
    def n_steps(self) -> int:
        """Number of steps taken so far (children and parent steps)."""
        return self._n_steps

    @property
    def timestamp(self) -> float:
        """Time of the last step, s."""
        return self._time

    @property
    def parent(self) -> ParentPoseBatch:
        """The parent's current pose estimates with their covariances."""
        return ParentPoseBatch(
            self._state[:, 0], self._state[:, 1:4], self._covariance[:, :4, :4], self._time
        )

    @property
    def state(self) -> NDArray[np.float64]:
        """(T, 4 + 3N) current joint states (NaN for children not yet placed)."""
        return self._state.copy()

    @property
    def state_covariance(self) -> NDArray[np.float64]:
        """(T, 4 + 3N, 4 + 3N) current joint covariances."""
        return self._covariance.copy()

    @property
    def lost(self) -> NDArray[np.bool_]:
        """(T,) True for trials lost to a parent step without a solution (poor geometry)."""
        return np.isnan(self._state[:, 0])

    @property
    def children_world(self) -> NDArray[np.float64]:
        """(T, N, 3) children's world estimates; NaN for children not yet placed."""
        return self._state[:, 4:].reshape(self.n_trials, -1, 3).copy()

    def child_position(self, name: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(T, 3) world positions and (T, 3, 3) covariances of a child's reference point."""
        k = self._child_index(name)
        if not self._known[k]:
            raise ValueError(f"child {name!r} has not been measured yet")
        s = slice(4 + 3 * k, 7 + 3 * k)
        return self._state[:, s].copy(), self._covariance[:, s, s].copy()

    # -- steps ---------------------------------------------------------------------------
    def children_moved(
        self, observations: Sequence[ChildObservationBatch], timestamp: float | None = None
    ) -> None:
        """Children moved and stopped; the parent (not moved) measured them in every trial.

        Each observed child is placed in the world from the parent's current estimates.
        """
        obs = self._check_observations(observations, minimum=1)
        yaw = np.ascontiguousarray(self._state[:, 0])
        t = self._state[:, 1:4]
        rot, rot_dot = rot_z(yaw), rot_z_derivative(yaw)
        n_trials, n = self._state.shape
        a = np.tile(np.eye(n), (n_trials, 1, 1))
        b = np.zeros((n_trials, n, 3 * len(obs)))
        points = np.stack([o.point_level for o in obs], axis=1)  # (T, m, 3)
        # d(R p + t) / d yaw of all the points at once, as the scalar sequence computes it.
        lever = points @ _transpose(rot_dot)
        x_new = self._state.copy()
        for j, o in enumerate(obs):
            k = self._index[o.child]
            s = slice(4 + 3 * k, 7 + 3 * k)
            x_new[:, s] = (rot @ points[:, j, :, None])[..., 0] + t
            a[:, s, :] = 0.0
            a[:, s, 0] = lever[:, j]
            a[:, s, 1:4] = np.eye(3)
            b[:, s, 3 * j : 3 * j + 3] = rot
            self._known[k] = True
        noise = block_diagonal(np.stack([o.covariance for o in obs], axis=1))
        self._commit(x_new, a, b, noise)
        self._advance(obs, timestamp)

    def parent_moved(
        self, observations: Sequence[ChildObservationBatch], timestamp: float | None = None
    ) -> CpsSolutionBatch:
        """The parent moved and measured two or more stationary children; solve its pose.

        Returns:
            The solutions, with per-trial flags: ``inconsistent`` (the scalar sequence
            would raise :class:`InconsistentChildrenError`; the solution is kept here),
            ``poor_geometry`` (no solution: the trial is lost) and ``poor_yaw``.
        """
        obs = self._check_observations(observations, minimum=2)
        ks = [self._index[o.child] for o in obs]
        unknown = [o.child for o, k in zip(obs, ks, strict=True) if not self._known[k]]
        if unknown:
            raise ValueError(
                f"children {unknown} were never placed in the world; measure them with "
                "children_moved before the parent moves"
            )
        n_trials, n = self._state.shape
        # The children may have crept while the parent drove; kept only if the step succeeds.
        prior = self._covariance.copy()
        add_creep(prior, self._known, self._creep)
        cols = np.concatenate([np.arange(4 + 3 * k, 7 + 3 * k) for k in ks])
        world = self._state[:, cols].reshape(n_trials, -1, 3)
        level = np.stack([o.point_level for o in obs], axis=1)
        cov_w = prior[:, cols][:, :, cols]
        cov_m = np.stack([o.covariance for o in obs], axis=1)
        stamp = self._stamp(obs, timestamp)
        kwargs = {
            "timestamp": stamp,
            "min_baseline": self._min_baseline,
            "max_yaw_std": self._max_yaw_std,
            "false_alarm_rate": self._false_alarm_rate,
        }
        if self._solver == "wls":
            solution = solve_wls_batch(world, level, cov_w, cov_m, **kwargs)
        else:
            solution = solve_closed_form_batch(world, level, cov_w, cov_m, **kwargs)
        a = np.tile(np.eye(n), (n_trials, 1, 1))
        a[:, :4, :] = 0.0
        a[:, :4, cols] = solution.children_jacobian
        b = np.zeros((n_trials, n, 3 * len(obs)))
        b[:, :4, :] = solution.measurement_jacobian
        x_new = self._state.copy()
        x_new[:, :4] = solution.pose.vector
        self._covariance = prior
        self._commit(x_new, a, b, block_diagonal(cov_m))
        lost = solution.poor_geometry
        self._state[lost] = np.nan
        self._covariance[lost] = np.nan
        self._advance(obs, timestamp)
        return solution

    # -- some trials only ----------------------------------------------------------------
    def trials(self, rows: NDArray[np.intp]) -> CpsBatch:
        """A batch of the trials ``rows`` (R,), as they stand: its steps change nothing here
        until :meth:`set_trials` writes them back."""
        part = copy.copy(self)
        part._state = self._state[rows]
        part._covariance = self._covariance[rows]
        part._known = self._known.copy()
        return part

    def set_trials(self, rows: NDArray[np.intp], part: CpsBatch) -> None:
        """Take the trials ``rows`` from ``part`` (made by :meth:`trials` with the same rows
        and stepped since). The other trials are kept; arrays read before stay as they were."""
        state, covariance = self._state.copy(), self._covariance.copy()
        state[rows], covariance[rows] = part._state, part._covariance
        self._state, self._covariance = state, covariance
        self._known |= part._known
        self._time = max(self._time, part._time)
        self._n_steps = max(self._n_steps, part._n_steps)

    def reset_trials(self, rows: NDArray[np.intp], initial_pose: ParentPose | None = None) -> None:
        """Start the trials ``rows`` again from ``initial_pose`` (default the world origin
        with zero covariance), no child placed. A child placed in another trial stays
        known to the batch: place it again in these trials before a parent step."""
        pose = ParentPose(0.0, np.zeros(3)) if initial_pose is None else initial_pose
        state, covariance = self._state.copy(), self._covariance.copy()
        state[rows] = np.nan
        state[rows, :4] = pose.vector
        covariance[rows] = 0.0
        covariance[np.ix_(rows, range(4), range(4))] = pose.covariance
        self._state, self._covariance = state, covariance

    # -- internals -----------------------------------------------------------------------
    def _child_index(self, name: str) -> int:
        return child_index(self._index, name)

    def _check_observations(
        self, observations: Sequence[ChildObservationBatch], minimum: int
    ) -> tuple[ChildObservationBatch, ...]:
        obs = tuple(observations)
        check_step_children(self._index, [o.child for o in obs], minimum)
        for o in obs:
            if o.n_trials != self.n_trials:
                raise ValueError(
                    f"the observation of {o.child!r} has {o.n_trials} trials, the batch "
                    f"{self.n_trials}"
                )
        return obs

    def _stamp(self, obs: tuple[ChildObservationBatch, ...], timestamp: float | None) -> float:
        return float(max(o.timestamp for o in obs)) if timestamp is None else float(timestamp)

    def _commit(self, x_new: NDArray, a: NDArray, b: NDArray, noise: NDArray) -> None:
        # Children not placed yet have NaN state and zero covariance rows; A keeps them so.
        p_new = a @ self._covariance @ _transpose(a) + b @ noise @ _transpose(b)
        self._state = x_new
        self._covariance = 0.5 * (p_new + _transpose(p_new))

    def _advance(self, obs: tuple[ChildObservationBatch, ...], timestamp: float | None) -> None:
        self._time = self._stamp(obs, timestamp)
        self._n_steps += 1
