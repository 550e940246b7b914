"""The CPS sequence: a record of every step and the joint estimate of all robots.

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
The same object serves a campaign, a Monte Carlo run, a gym environment and a later
global adjustment (which reads :attr:`CpsSequence.steps`).

A parent step whose children fail the solver's chi-square test raises
:class:`InconsistentChildrenError` (a child moved between the two measurements, or a wrong
prism) and leaves the sequence unchanged: the caller can count it, measure again and call
:meth:`CpsSequence.parent_moved` with the new observations.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from calib.rotation import rot_z
from twin.instruments.consistency import DEFAULT_FALSE_ALARM_RATE, check_false_alarm_rate
from twin.localization.closed_form import solve_closed_form
from twin.localization.input_checks import DEFAULT_MAX_YAW_STD, DEFAULT_MIN_BASELINE
from twin.localization.observation import ChildObservation
from twin.localization.pose import CpsSolution, ParentPose
from twin.localization.propagation import level2world_jacobian
from twin.localization.wls import solve_wls

SOLVERS = ("wls", "closed_form")


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


class CpsSequence:
    """Joint estimate of a parent and its children along a CPS run, with the step record.

    Args:
        children: the children's names, in state order.
        initial_pose: the parent's pose at its first station; default the world origin
            with zero covariance (the world is the parent's first levelled frame).
        solver: ``"wls"`` (any number >= 2 of children) or ``"closed_form"`` (exactly two).
        min_baseline, max_yaw_std: passed to the solver (see :mod:`.input_checks`).
        false_alarm_rate: passed to the solver: probability that consistent data raise
            :class:`InconsistentChildrenError` at a parent step; None switches it off.
        child_creep: how far a standing child may move on each horizontal axis while the
            parent drives, m (standard deviation): added to every placed child's position
            covariance at each parent step, before the solve (default 0).
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
        names = check_children_and_solver(children, solver)
        pose = initial_pose if initial_pose is not None else ParentPose(0.0, np.zeros(3))
        self._children = names
        self._index = {name: i for i, name in enumerate(names)}
        self._solver = solver
        self._min_baseline = min_baseline
        self._max_yaw_std = max_yaw_std
        self._false_alarm_rate = check_false_alarm_rate(false_alarm_rate)
        self._creep = check_creep(child_creep)
        n = 4 + 3 * len(names)
        self._state = np.full(n, np.nan)
        self._state[:4] = pose.vector
        self._covariance = np.zeros((n, n))
        self._covariance[:4, :4] = pose.covariance
        self._known = np.zeros(len(names), dtype=bool)
        self._time = pose.timestamp
        self._steps: list[CpsStep] = []
        self._parent: ParentPose | None = None  # the pose of the current state, once built

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
    def parent(self) -> ParentPose:
        """The parent's current pose estimate with its covariance."""
        if self._parent is None:
            self._parent = ParentPose(
                self._state[0], self._state[1:4], self._covariance[:4, :4].copy(), self._time
            )
        return self._parent

    @property
    def state(self) -> NDArray[np.float64]:
        """(4 + 3N,) current joint state (NaN for children not yet placed)."""
        return self._state.copy()

    @property
    def state_covariance(self) -> NDArray[np.float64]:
        """(4 + 3N, 4 + 3N) current joint covariance."""
        return self._covariance.copy()

    @property
    def steps(self) -> tuple[CpsStep, ...]:
        """Every step so far, in order."""
        return tuple(self._steps)

    def child_position(self, name: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(3,) world position and (3, 3) covariance of a child's reference point."""
        k = self._child_index(name)
        if not self._known[k]:
            raise ValueError(f"child {name!r} has not been measured yet")
        s = slice(4 + 3 * k, 7 + 3 * k)
        return self._state[s].copy(), self._covariance[s, s].copy()

    # -- steps ---------------------------------------------------------------------------
    def children_moved(
        self, observations: Sequence[ChildObservation], timestamp: float | None = None
    ) -> CpsStep:
        """Children moved and stopped; the parent (not moved) measured them.

        Each observed child is placed in the world from the parent's current estimate.
        """
        obs = self._check_observations(observations, minimum=1)
        yaw, t = self._state[0], self._state[1:4]
        rot = rot_z(yaw)
        jac_parent = level2world_jacobian(yaw, [o.point_level for o in obs])
        n = self._state.size
        a = np.eye(n)
        b = np.zeros((n, 3 * len(obs)))
        noise = np.zeros((3 * len(obs), 3 * len(obs)))
        x_new = self._state.copy()
        for j, o in enumerate(obs):
            k = self._index[o.child]
            s = slice(4 + 3 * k, 7 + 3 * k)
            x_new[s] = rot @ o.point_level + t
            a[s, :] = 0.0
            a[s, :4] = jac_parent[j]
            b[s, 3 * j : 3 * j + 3] = rot
            noise[3 * j : 3 * j + 3, 3 * j : 3 * j + 3] = o.covariance
            self._known[k] = True
        self._commit(x_new, a, b, noise)
        return self._record(StepKind.CHILDREN_MOVED, obs, tuple(o.child for o in obs), timestamp)

    def parent_moved(
        self, observations: Sequence[ChildObservation], timestamp: float | None = None
    ) -> CpsStep:
        """The parent moved and measured two or more stationary children; solve its pose.

        Raises:
            InconsistentChildrenError: the children do not fit their world positions (see
                the module text); nothing is recorded and the state is unchanged.
        """
        obs = self._check_observations(observations, minimum=2)
        ks = [self._index[o.child] for o in obs]
        unknown = [o.child for o, k in zip(obs, ks, strict=True) if not self._known[k]]
        if unknown:
            raise ValueError(
                f"children {unknown} were never placed in the world; measure them with "
                "children_moved before the parent moves"
            )
        # The children may have crept while the parent drove; kept only if the step succeeds.
        prior = self._covariance.copy()
        add_creep(prior, self._known, self._creep)
        cols = np.concatenate([np.arange(4 + 3 * k, 7 + 3 * k) for k in ks])
        world = self._state[cols].reshape(-1, 3)
        level = np.array([o.point_level for o in obs])
        cov_w = prior[np.ix_(cols, cols)]
        cov_m = np.array([o.covariance for o in obs])
        stamp = self._stamp(obs, timestamp)
        kwargs = {
            "timestamp": stamp,
            "min_baseline": self._min_baseline,
            "max_yaw_std": self._max_yaw_std,
            "false_alarm_rate": self._false_alarm_rate,
        }
        if self._solver == "wls":
            solution = solve_wls(world, level, cov_w, cov_m, **kwargs)
        else:
            solution = solve_closed_form(world, level, cov_w, cov_m, **kwargs)
        n = self._state.size
        a = np.eye(n)
        a[:4, :] = 0.0
        a[:4, cols] = solution.children_jacobian
        b = np.zeros((n, 3 * len(obs)))
        b[:4, :] = solution.measurement_jacobian
        noise = np.zeros((3 * len(obs), 3 * len(obs)))
        for j, o in enumerate(obs):
            noise[3 * j : 3 * j + 3, 3 * j : 3 * j + 3] = o.covariance
        x_new = self._state.copy()
        x_new[:4] = solution.pose.vector
        self._covariance = prior
        self._commit(x_new, a, b, noise)
        return self._record(StepKind.PARENT_MOVED, obs, ("parent",), stamp, solution)

    # -- internals -----------------------------------------------------------------------
    def _child_index(self, name: str) -> int:
        return child_index(self._index, name)

    def _check_observations(
        self, observations: Sequence[ChildObservation], minimum: int
    ) -> tuple[ChildObservation, ...]:
        obs = tuple(observations)
        check_step_children(self._index, [o.child for o in obs], minimum)
        return obs

    def _stamp(self, obs: tuple[ChildObservation, ...], timestamp: float | None) -> float:
        return float(max(o.timestamp for o in obs)) if timestamp is None else float(timestamp)

    def _commit(self, x_new: NDArray, a: NDArray, b: NDArray, noise: NDArray) -> None:
        # Children not placed yet have NaN state and zero covariance rows; A keeps them so.
        p_new = a @ self._covariance @ a.T + b @ noise @ b.T
        self._state = x_new
        self._covariance = 0.5 * (p_new + p_new.T)
        self._parent = None

    def _record(
        self,
        kind: StepKind,
        obs: tuple[ChildObservation, ...],
        moved: tuple[str, ...],
        timestamp: float | None,
        solution: CpsSolution | None = None,
    ) -> CpsStep:
        self._time = self._stamp(obs, timestamp)
        self._parent = None
        step = CpsStep(
            index=len(self._steps),
            kind=kind,
            timestamp=self._time,
            moved=moved,
            observations=obs,
            parent=self.parent,
            children_world=self._state[4:].reshape(-1, 3).copy(),
            state_covariance=self._covariance.copy(),
            solution=solution,
        )
        self._steps.append(step)
        return step
