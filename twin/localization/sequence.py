"""The CPS sequence of one trial: the joint estimate of all robots and a record of every step.

:class:`CpsSequence` is one trial of :class:`twin.localization.joint_state.CpsBatch` (the
joint state, its covariance and the two kinds of step are described there), solved with
the one-trial solvers, so that it raises where the batch flags, and keeping the record of
its steps (:class:`CpsStep`). The same object serves a campaign, a gym environment and a
later global adjustment (which reads :attr:`CpsSequence.steps`).

A parent step whose children fail the solver's chi-square test raises
:class:`InconsistentChildrenError` (a child moved between the two measurements, or a wrong
prism) and leaves the sequence unchanged: the caller can count it, measure again and call
:meth:`CpsSequence.parent_moved` with the new observations.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from twin.instruments.consistency import DEFAULT_FALSE_ALARM_RATE
from twin.localization.closed_form import solve_closed_form
from twin.localization.input_checks import DEFAULT_MAX_YAW_STD, DEFAULT_MIN_BASELINE
from twin.localization.joint_state import CpsBatch, step_time
from twin.localization.observation import ChildObservation
from twin.localization.pose import CpsSolution, ParentPose
from twin.localization.wls import solve_wls


class StepKind(enum.Enum):
    """What happened in a CPS step."""

    CHILDREN_MOVED = "children_moved"
    PARENT_MOVED = "parent_moved"


@dataclass(frozen=True, eq=False)
class CpsStep:
    """One recorded step.

    Attributes:
        index: 0, 1, ... in the order the steps happened.
        kind: which robots moved.
        timestamp: time of the step, s.
        moved: names of the robots that moved before the measurements ("parent" or children).
        observations: what the parent measured at this step.
        parent: the parent's pose estimate after the step.
        children_world: (N, 3) children's world estimates after the step, in the order of
            :attr:`CpsSequence.children`; NaN rows for children not yet placed.
        state_covariance: (4 + 3N, 4 + 3N) joint covariance after the step.
        solution: the CPS solution (parent steps only).
    """

    index: int
    kind: StepKind
    timestamp: float
    moved: tuple[str, ...]
    observations: tuple[ChildObservation, ...]
    parent: ParentPose
    children_world: NDArray[np.float64]
    state_covariance: NDArray[np.float64]
    solution: CpsSolution | None = None

    def __post_init__(self) -> None:
        for name in ("children_world", "state_covariance"):
            arr = np.array(getattr(self, name), dtype=float)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)


class CpsSequence:
    """Joint estimate of a parent and its children along a CPS run, with the step record:
    one trial of :class:`CpsBatch`, raising where the batch flags.

    Args:
        children: the children's names, in state order.
        initial_pose: the parent's pose at its first station; default the world origin
            with zero covariance (the world is the parent's first levelled frame).
        solver: ``"wls"`` (any number >= 2 of children) or ``"closed_form"`` (exactly two).
        min_baseline, max_yaw_std: passed to the solver (see :mod:`.input_checks`).
        false_alarm_rate: passed to the solver: probability that consistent data raise
            :class:`InconsistentChildrenError` at a parent step; None switches it off.
        child_creep: as :class:`CpsBatch`'s, m.
    """

    def __init__(
        self,
        children: Sequence[str],
        initial_pose: ParentPose | None = None,
        *,
        solver: str = "wls",
        min_baseline: float = DEFAULT_MIN_BASELINE,
        max_yaw_std: float = DEFAULT_MAX_YAW_STD,
        false_alarm_rate: float | None = DEFAULT_FALSE_ALARM_RATE,
        child_creep: float = 0.0,
    ) -> None:
        self._batch = CpsBatch(
            children,
            1,
            initial_pose,
            solver=solver,
            min_baseline=min_baseline,
            max_yaw_std=max_yaw_std,
            false_alarm_rate=false_alarm_rate,
            child_creep=child_creep,
        )
        self._steps: list[CpsStep] = []
        self._parent: ParentPose | None = None  # the pose of the current state, once built

    # -- read access ---------------------------------------------------------------------
    @property
    def children(self) -> tuple[str, ...]:
        """The children's names in state order."""
        return self._batch.children

    @property
    def solver(self) -> str:
        """The CPS solver used for parent steps."""
        return self._batch.solver

    @property
    def parent(self) -> ParentPose:
        """The parent's current pose estimate with its covariance."""
        if self._parent is None:
            self._parent = self._batch.parent.trial(0)
        return self._parent

    @property
    def state(self) -> NDArray[np.float64]:
        """(4 + 3N,) current joint state (NaN for children not yet placed)."""
        return self._batch.state[0]

    @property
    def state_covariance(self) -> NDArray[np.float64]:
        """(4 + 3N, 4 + 3N) current joint covariance."""
        return self._batch.state_covariance[0]

    @property
    def steps(self) -> tuple[CpsStep, ...]:
        """Every step so far, in order."""
        return tuple(self._steps)

    def child_position(self, name: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(3,) world position and (3, 3) covariance of a child's reference point."""
        position, covariance = self._batch.child_position(name)
        return position[0], covariance[0]

    # -- steps ---------------------------------------------------------------------------
    def children_moved(
        self, observations: Sequence[ChildObservation], timestamp: float | None = None
    ) -> CpsStep:
        """Children moved and stopped; the parent (not moved) measured them.

        Each observed child is placed in the world from the parent's current estimate.
        """
        obs = tuple(observations)
        names = [o.child for o in obs]
        points = np.array([o.point_level for o in obs])[None]
        covariances = np.array([o.covariance for o in obs])[None]
        self._batch.place(names, points, covariances, step_time(obs, timestamp))
        return self._record(StepKind.CHILDREN_MOVED, obs, tuple(names))

    def parent_moved(
        self, observations: Sequence[ChildObservation], timestamp: float | None = None
    ) -> CpsStep:
        """The parent moved and measured two or more stationary children; solve its pose.

        Raises:
            InconsistentChildrenError: the children do not fit their world positions (see
                the module text); nothing is recorded and the state is unchanged.
        """
        obs = tuple(observations)
        batch = self._batch
        problem = batch.parent_problem([o.child for o in obs], step_time(obs, timestamp))
        level = np.array([o.point_level for o in obs])
        cov_m = np.array([o.covariance for o in obs])
        solve = solve_wls if batch.solver == "wls" else solve_closed_form
        solution = solve(
            problem.world[0], level, problem.world_covariance[0], cov_m, **problem.options
        )
        batch.take_parent(
            problem,
            solution.pose.vector[None],
            solution.children_jacobian[None],
            solution.measurement_jacobian[None],
            cov_m[None],
        )
        return self._record(StepKind.PARENT_MOVED, obs, ("parent",), solution)

    # -- internals -----------------------------------------------------------------------
    def _record(
        self,
        kind: StepKind,
        obs: tuple[ChildObservation, ...],
        moved: tuple[str, ...],
        solution: CpsSolution | None = None,
    ) -> CpsStep:
        self._parent = None
        step = CpsStep(
            index=len(self._steps),
            kind=kind,
            timestamp=self._batch.timestamp,
            moved=moved,
            observations=obs,
            parent=self.parent,
            children_world=self.state[4:].reshape(-1, 3),
            state_covariance=self.state_covariance,
            solution=solution,
        )
        self._steps.append(step)
        return step
