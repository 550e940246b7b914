"""The joint estimate of a parent and its children over T trials, and its two updates.

The state is ``x = (parent yaw, parent x, y, z, child_1 xyz, ..., child_N xyz)`` in the
world frame with its full joint covariance ``P``. Two kinds of step alternate:

- children moved: they stopped and the parent measured them. Each measured child's state
  is replaced by ``Rz(yaw) m + t`` (paper eq. 1); its covariance inherits the parent's
  (``J_parent P J_parent^T + Rz Cov(m) Rz^T``) and so do its cross terms with every other
  robot. That is how two children end up correlated with each other.
- parent moved: it measured two or more stationary children and solved its own pose
  (closed form or WLS). The parent's state is replaced by the solution; its covariance is
  ``G_w P_cc G_w^T + G_m Cov(m) G_m^T`` and its cross terms follow from ``G_w``.

Both updates are one linear map ``x' = A x + B noise``, ``P' = A P A^T + B Cov B^T``, so
nothing is double-counted and the error grows with distance as the paper's Table III shows.

:class:`CpsBatch` runs T trials at once: the trials share the children, the solver and the
order of the steps; each has its own measurements, state ``x`` (T, 4 + 3N) and covariance
``P`` (T, 4 + 3N, 4 + 3N), updated by its own ``A`` and ``B``, so a trial does not depend
on the others. What one trial's data make the solver raise, the batch flags and goes on: a
child that does not fit (:attr:`CpsSolutionBatch.inconsistent`) keeps its solution for the
caller to count; a horizontal baseline below ``min_baseline`` loses the trial
(:attr:`CpsBatch.lost`: NaN from then on). The batch keeps no step record (at T trials it
would be T times the one-trial record); each parent step returns its solutions. A parent
step is also open in its two halves (:meth:`CpsBatch.parent_problem`, then
:meth:`CpsBatch.take_parent`) for a caller that solves with its own solver:
:class:`twin.localization.sequence.CpsSequence`, one trial that raises where the batch flags.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from calib.rotation import rot_z, rot_z_derivative
from twin.instruments.consistency import DEFAULT_FALSE_ALARM_RATE, check_false_alarm_rate
from twin.localization.closed_form import solve_closed_form_batch
from twin.localization.input_checks import (
    DEFAULT_MAX_YAW_STD,
    DEFAULT_MIN_BASELINE,
    block_diagonal,
)
from twin.localization.observation import ChildObservation, ChildObservationBatch
from twin.localization.pose import CpsSolutionBatch, ParentPose, ParentPoseBatch
from twin.localization.wls import solve_wls_batch

SOLVERS = ("wls", "closed_form")


@dataclass(frozen=True, eq=False)
class ParentProblem:
    """What a parent step that measured m children solves, in T trials.

    Attributes:
        prior: (T, n, n) joint covariances before the step, with the children's creep.
        columns: (3m,) the measured children's columns in the state.
        world: (T, m, 3) the children's world positions, m.
        world_covariance: (T, 3m, 3m) their joint covariance, m^2.
        options: the solver's keyword arguments (``timestamp``, ``min_baseline``,
            ``max_yaw_std``, ``false_alarm_rate``).
    """

    prior: NDArray[np.float64]
    columns: NDArray[np.intp]
    world: NDArray[np.float64]
    world_covariance: NDArray[np.float64]
    options: dict[str, Any]


def step_time(
    observations: Sequence[ChildObservation | ChildObservationBatch], timestamp: float | None
) -> float:
    """A step's time, s: ``timestamp``, or the latest observation's when None."""
    if timestamp is None:
        return float(max(o.timestamp for o in observations))
    return float(timestamp)


def child_index(index: Mapping[str, int], name: str) -> int:
    """A child's place in the state; a named error for an unknown child."""
    try:
        return index[name]
    except KeyError:
        raise ValueError(f"unknown child {name!r}; children are {list(index)}") from None


def check_step_children(index: Mapping[str, int], names: Sequence[str], minimum: int) -> None:
    """Refuse a step that observes fewer than ``minimum`` children, an unknown child, or
    one child twice."""
    if len(names) < minimum:
        raise ValueError(
            f"this step needs at least {minimum} child observation(s), got {len(names)}"
        )
    for name in names:
        child_index(index, name)
    if len(set(names)) != len(names):
        raise ValueError(f"a child is observed twice in one step: {list(names)}")


def check_children_and_solver(children: Sequence[str], solver: str) -> tuple[str, ...]:
    """The children's names as a tuple, if there are two or more, all distinct and none
    called ``parent``, and ``solver`` is one of :data:`SOLVERS`; ValueError otherwise."""
    names = tuple(children)
    if len(names) < 2:
        raise ValueError(f"CPS needs at least two children, got {list(names)}")
    if len(set(names)) != len(names) or "parent" in names:
        raise ValueError(f"children names must be unique and not 'parent', got {list(names)}")
    if solver not in SOLVERS:
        raise ValueError(f"solver must be one of {SOLVERS}, got {solver!r}")
    return names


def check_creep(creep: float) -> float:
    """``creep`` (m) if finite and non-negative; ValueError naming it otherwise."""
    if not (np.isfinite(creep) and creep >= 0):
        raise ValueError(f"child_creep must be finite and non-negative (m), got {creep}")
    return float(creep)


def add_creep(covariance: NDArray[np.float64], known: NDArray[np.bool_], creep: float) -> None:
    """Add a standing child's creep to the joint covariance, in place: ``creep**2`` (m^2)
    on the x and y variances of every child in ``known`` (N,). ``covariance``: (..., n, n)
    joint covariances (``n = 4 + 3N``), one per trial or one."""
    if creep <= 0:
        return
    for k in np.flatnonzero(known):
        for axis in (0, 1):
            i = 4 + 3 * k + axis
            covariance[..., i, i] += creep**2


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
        child_creep: how far a standing child may move on each horizontal axis while the
            parent drives, m (standard deviation): added to every placed child's position
            covariance at each parent step, before the solve (default 0).
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
        points = np.stack([o.point_level for o in obs], axis=1)  # (T, m, 3)
        covariances = np.stack([o.covariance for o in obs], axis=1)  # (T, m, 3, 3)
        self.place([o.child for o in obs], points, covariances, step_time(obs, timestamp))

    def parent_moved(
        self, observations: Sequence[ChildObservationBatch], timestamp: float | None = None
    ) -> CpsSolutionBatch:
        """The parent moved and measured two or more stationary children; solve its pose.

        Returns:
            The solutions, with per-trial flags: ``inconsistent`` (:class:`CpsSequence`
            would raise :class:`InconsistentChildrenError`; the solution is kept here),
            ``poor_geometry`` (no solution: the trial is lost) and ``poor_yaw``.
        """
        obs = self._check_observations(observations, minimum=2)
        problem = self.parent_problem([o.child for o in obs], step_time(obs, timestamp))
        level = np.stack([o.point_level for o in obs], axis=1)
        cov_m = np.stack([o.covariance for o in obs], axis=1)
        solve = solve_wls_batch if self._solver == "wls" else solve_closed_form_batch
        solution = solve(problem.world, level, problem.world_covariance, cov_m, **problem.options)
        self.take_parent(
            problem,
            solution.pose.vector,
            solution.children_jacobian,
            solution.measurement_jacobian,
            cov_m,
        )
        lost = solution.poor_geometry
        self._state[lost] = np.nan
        self._covariance[lost] = np.nan
        return solution

    # -- a step in parts, for a caller's own solver ----------------------------------------
    def place(
        self,
        names: Sequence[str],
        points: NDArray[np.float64],
        covariances: NDArray[np.float64],
        timestamp: float,
    ) -> None:
        """The children step of :meth:`children_moved` from arrays: the children ``names``
        (m) measured at (T, m, 3) points in the levelled frame, m, with (T, m, 3, 3)
        covariances, m^2, at ``timestamp``, s."""
        check_step_children(self._index, names, 1)
        self._place(names, points, covariances)
        self._advance(timestamp)

    def parent_problem(self, names: Sequence[str], timestamp: float) -> ParentProblem:
        """The first half of a parent step that measured the children ``names`` at
        ``timestamp``, s: what its solver solves. Nothing changes until :meth:`take_parent`."""
        prior, cols, world, cov_w = self._parent_problem(names)
        return ParentProblem(prior, cols, world, cov_w, self._solver_options(timestamp))

    def take_parent(
        self,
        problem: ParentProblem,
        pose: NDArray[np.float64],
        children_jacobian: NDArray[np.float64],
        measurement_jacobian: NDArray[np.float64],
        measurement_covariance: NDArray[np.float64],
    ) -> None:
        """The second half of a parent step: take the solved (T, 4) parent poses, with
        their (T, 4, 3m) Jacobians with respect to the children's world positions and to
        the measurements and the (T, m, 3, 3) measurement covariances, m^2."""
        self._parent_update(
            problem.prior,
            problem.columns,
            pose,
            children_jacobian,
            measurement_jacobian,
            measurement_covariance,
        )
        self._advance(problem.options["timestamp"])

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
    def _place(
        self, names: Sequence[str], points: NDArray[np.float64], covariances: NDArray[np.float64]
    ) -> None:
        """Place the children ``names`` (m) in the world from their (T, m, 3) points in the
        levelled frame, m, with (T, m, 3, 3) covariances, m^2."""
        yaw = np.ascontiguousarray(self._state[:, 0])
        t = self._state[:, 1:4]
        rot, rot_dot = rot_z(yaw), rot_z_derivative(yaw)
        n_trials, n = self._state.shape
        a = np.tile(np.eye(n), (n_trials, 1, 1))
        b = np.zeros((n_trials, n, 3 * len(names)))
        lever = points @ rot_dot.mT  # d(R p + t) / d yaw of every point
        x_new = self._state.copy()
        for j, name in enumerate(names):
            k = self._index[name]
            s = slice(4 + 3 * k, 7 + 3 * k)
            x_new[:, s] = (rot @ points[:, j, :, None])[..., 0] + t
            a[:, s, :] = 0.0
            a[:, s, 0] = lever[:, j]
            a[:, s, 1:4] = np.eye(3)
            b[:, s, 3 * j : 3 * j + 3] = rot
            self._known[k] = True
        self._commit(x_new, a, b, block_diagonal(covariances))

    def _parent_problem(
        self, names: Sequence[str]
    ) -> tuple[NDArray[np.float64], NDArray[np.intp], NDArray[np.float64], NDArray[np.float64]]:
        """What a parent step that measured the children ``names`` solves: the prior
        covariance (T, n, n) with the children's creep, the state columns of the children,
        their (T, m, 3) world positions and (T, 3m, 3m) joint covariance."""
        check_step_children(self._index, names, 2)
        ks = [self._index[name] for name in names]
        unknown = [name for name, k in zip(names, ks, strict=True) if not self._known[k]]
        if unknown:
            raise ValueError(
                f"children {unknown} were never placed in the world; measure them with "
                "children_moved before the parent moves"
            )
        # The children may have crept while the parent drove; kept only if the step succeeds.
        prior = self._covariance.copy()
        add_creep(prior, self._known, self._creep)
        cols = np.concatenate([np.arange(4 + 3 * k, 7 + 3 * k) for k in ks])
        world = self._state[:, cols].reshape(self.n_trials, -1, 3)
        return prior, cols, world, prior[:, cols][:, :, cols]

    def _solver_options(self, stamp: float) -> dict[str, float | None]:
        return {
            "timestamp": stamp,
            "min_baseline": self._min_baseline,
            "max_yaw_std": self._max_yaw_std,
            "false_alarm_rate": self._false_alarm_rate,
        }

    def _parent_update(
        self,
        prior: NDArray[np.float64],
        cols: NDArray[np.intp],
        pose: NDArray[np.float64],
        children_jacobian: NDArray[np.float64],
        measurement_jacobian: NDArray[np.float64],
        cov_m: NDArray[np.float64],
    ) -> None:
        """Take the solved (T, 4) parent poses, with their (T, 4, 3m) Jacobians and the
        (T, m, 3, 3) measurement covariances, into the state from the ``prior``."""
        n_trials, n = self._state.shape
        a = np.tile(np.eye(n), (n_trials, 1, 1))
        a[:, :4, :] = 0.0
        a[:, :4, cols] = children_jacobian
        b = np.zeros((n_trials, n, cols.size))
        b[:, :4, :] = measurement_jacobian
        x_new = self._state.copy()
        x_new[:, :4] = pose
        self._covariance = prior
        self._commit(x_new, a, b, block_diagonal(cov_m))

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

    def _commit(self, x_new: NDArray, a: NDArray, b: NDArray, noise: NDArray) -> None:
        # Children not placed yet have NaN state and zero covariance rows; A keeps them so.
        p_new = a @ self._covariance @ a.mT + b @ noise @ b.mT
        self._state = x_new
        self._covariance = 0.5 * (p_new + p_new.mT)

    def _advance(self, timestamp: float) -> None:
        self._time = timestamp
        self._n_steps += 1
