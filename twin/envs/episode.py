"""An episode of the environment: the campaign it plays (an :class:`EpisodePlanner`) and
the trial that executes its steps with noise (an :class:`Episode`).

The planners (:mod:`twin.envs.planner`, :mod:`twin.envs.stands`) answer the environment's
questions through :class:`EpisodePlanner`. :class:`Episode` holds one episode: its planner,
its trial (a row of a :class:`twin.batch.execute.BatchRun`), what its moves have earned
and what it observes. :class:`twin.envs.campaign_env.CpsCampaignEnv` plays one episode at
a time; :class:`twin.envs.vector.CpsCampaignVectorEnv` plays many, their trials rows of
shared batches, through the same object.
"""

from __future__ import annotations

import abc
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from twin.batch.execute import BatchRun
from twin.batch.steps import BatchPlan, Step
from twin.envs.free_space import FreeSpace
from twin.envs.knowledge import BatchKnowledge, Knowledge
from twin.envs.moves import MoveLayout
from twin.envs.observation import CameraState, SiteScale, Stations, build_observations
from twin.envs.site_stations import START, Station
from twin.scenario.schema import Scenario

__all__ = [
    "LEG",
    "MOVED_M",
    "VISIT",
    "Episode",
    "EpisodePlanner",
    "EpisodeSettings",
    "SiteShare",
    "calibrated_since_moved",
]


class SiteShare(Protocol):
    """What the planners of one site in one process share: the campaign's plan before its
    first step, and the plan's steps of its start (the reference data)."""

    @property
    def plan(self) -> BatchPlan: ...

    @property
    def start(self) -> tuple[Step, ...]: ...


LEG = "leg"
"""A decision about the next leg of a travel."""


VISIT = "visit"
"""A decision between travels: calibrate here, go somewhere, or end."""


def calibrated_since_moved(calibrated_at: dict[str, float], camera: str, travelled: float) -> bool:
    """Whether ``camera`` was calibrated and the parent has not moved since: its travel
    (m) is the one recorded in ``calibrated_at`` (the parent's travel at each camera's last
    calibration, m). ``calibrate`` is then forbidden: a repeated data set from the same
    place would only draw the noise again (and the best of a camera's visits is the one
    delivered)."""
    at = calibrated_at.get(camera)
    return at is not None and travelled - at < MOVED_M


MOVED_M = 1e-6
"""Travel of the parent after which the group has moved (a calibration can be repeated), m."""


def visit_mask(
    mask: NDArray[np.bool_],
    layout: MoveLayout,
    order: tuple[str, ...],
    here: str | None,
    calibrate: bool,
    distance: Callable[[str], float],
    left: float,
) -> None:
    """Set ``mask`` (n,) to the moves allowed between travels: ``calibrate`` where the
    camera of the station ``here`` can be calibrated (and was not calibrated since the
    group last moved: :func:`calibrated_since_moved`), a travel to each other station of
    ``order`` (``go_to``) and back to the start whose route ``distance`` (by the station's
    name, m) fits in what is ``left`` of the budget (m), and ``end``."""
    mask[:] = False
    mask[layout.calibrate] = calibrate
    for k, name in enumerate(order):
        if name != here:
            mask[layout.go_to(k)] = distance(name) <= left
    if here != START:
        mask[layout.return_start] = distance(START) <= left
    mask[layout.end] = True


class EpisodePlanner(abc.ABC):
    """What an environment asks of the campaign it plays, decision by decision (the
    campaign itself: :class:`twin.envs.planner.CampaignPlanner`; a site's table:
    :class:`twin.envs.stands.StandPlanner`).

    Attributes:
        layout: the moves. budget_m: the parent's travel allowed, m.
        stations: the calibration stations and ``start``, by name. order: the calibration
            stations' names in the order of ``go_to``.
    """

    layout: MoveLayout
    budget_m: float
    stations: dict[str, Station]
    order: tuple[str, ...]
    decision: str | None  # ``leg``, ``visit``, or None once the campaign is over
    time: float  # the campaign's time so far, s
    _pending: tuple[Step, ...]

    @property
    @abc.abstractmethod
    def memo(self) -> SiteShare:
        """What the planners of a site in one process share (its plan, its start)."""

    @property
    def plan(self) -> BatchPlan:
        """The campaign's plan before its first step."""
        return self.memo.plan

    @property
    @abc.abstractmethod
    def mask(self) -> NDArray[np.bool_]:
        """(n,) the moves allowed now (read-only)."""

    @abc.abstractmethod
    def here(self) -> str | None:
        """The station the parent stands at, or None."""

    @property
    @abc.abstractmethod
    def goal_station(self) -> Station | None:
        """The station the group travels to, during a travel."""

    @abc.abstractmethod
    def route_distance(self, station: Station) -> float:
        """The parent's travel along the route to a station, m."""

    @abc.abstractmethod
    def close(self) -> None:
        """Free what the planner holds of the campaign."""

    @abc.abstractmethod
    def _take(self, action: int) -> tuple[Step, ...]:
        """Take an allowed move (checked); the plan's steps until the next decision."""

    @property
    def done(self) -> bool:
        """Whether the campaign is over."""
        return self.decision is None

    def here_camera(self) -> str | None:
        """The camera whose station the parent stands at, or None."""
        here = self.here()
        return None if here is None else self.stations[here].camera

    def take_pending(self) -> tuple[Step, ...]:
        """The plan's steps before the first decision (the reference data), once."""
        steps, self._pending = self._pending, ()
        return steps

    def act(self, action: int) -> tuple[Step, ...]:
        """Take an allowed move; the plan's steps until the next decision.

        Raises:
            ValueError: ``action`` is not in the action space
                (:meth:`twin.envs.moves.MoveLayout.check`), or the move is not allowed now
                (see :attr:`mask`).
            RuntimeError: the campaign is over.
        """
        if self.done:
            raise RuntimeError("the campaign is over: no move to take")
        action = self.layout.check(action)
        if not self.mask[action]:
            raise ValueError(f"{self.layout.describe(action)} is not allowed now")
        return self._take(action)


@dataclass(frozen=True)
class EpisodeSettings:
    """What an environment's settings ask of each episode (see
    :class:`twin.envs.campaign_env.CpsCampaignEnv`).

    Attributes:
        layout: the moves. strict: raise on a forbidden move instead of running its
            fallback. reward_mode: ``predicted`` or ``truth``.
        cost_per_m, cost_per_s: the predicted reward's cost of travel (mm per metre) and
            of time (per second). uncalibrated_error_mm: the error counted for a camera
            not calibrated, mm. max_cameras: cameras the observation has room for.
    """

    layout: MoveLayout
    strict: bool
    reward_mode: str
    cost_per_m: float
    cost_per_s: float
    uncalibrated_error_mm: float
    max_cameras: int


class Episode:
    """One campaign an environment plays: its planner, the trial that executes its steps
    (row :attr:`row` of :attr:`batch`), and what its moves have earned.

    A move is resolved (:meth:`resolve`: the move or its fallback), taken by the planner
    (:meth:`EpisodePlanner.act`, giving the plan's steps), executed by the batch, then
    accounted for (:meth:`account`: the reward) and reported (:meth:`finish`);
    :meth:`apply` does the middle three for an episode that has its batch to itself.

    Args:
        scenario: the site. trial_seed: the trial's noise seed.
        planner: the episode's campaign. free_space: the site's free space (the
            observation's rays). settings: the environment's.

    Attributes:
        start_steps: the plan's steps before the first decision (the reference data), to
            execute before :meth:`attach`.
        moves: the moves taken, in order. steps: the plan's steps executed.
        fallbacks: forbidden moves replaced by their fallback.
    """

    def __init__(
        self,
        scenario: Scenario,
        trial_seed: int,
        planner: EpisodePlanner,
        free_space: FreeSpace,
        settings: EpisodeSettings,
    ) -> None:
        self.scenario, self.trial_seed, self.planner = scenario, trial_seed, planner
        self.free_space, self.settings = free_space, settings
        self.site_scale = SiteScale.of(scenario.space)
        self.start_steps = planner.take_pending()
        self.moves: list[int] = []
        self.steps: list[Step] = []
        self.fallbacks = 0
        self.batch: BatchRun | None = None
        self.row = 0
        self._known: BatchKnowledge | None = None
        self._time = self._distance = self._predicted = 0.0

    # -- the trial -----------------------------------------------------------------------------
    def knowledge_of(self, batch: BatchRun) -> BatchKnowledge:
        """What a batch of the episode's campaign knows (see :mod:`twin.envs.knowledge`)."""
        cameras = self.scenario.cameras
        return BatchKnowledge(
            batch, tuple(c.name for c in cameras), np.array([c.position for c in cameras])
        )

    def attach(
        self, batch: BatchRun, row: int, steps: tuple[Step, ...], known: BatchKnowledge | None
    ) -> None:
        """The episode's trial is row ``row`` of ``batch``, which has executed ``steps``
        (``known``: the batch's knowledge, shared with the other episodes of the batch;
        None: the episode's own)."""
        self.batch, self.row = batch, row
        self._known = known if known is not None else self.knowledge_of(batch)
        self.steps = list(steps)
        self._time = self.planner.time
        self._distance = 0.0
        self._predicted = self.mean_predicted_mm()
        self.fallbacks = 0

    @property
    def plan(self) -> BatchPlan:
        """The campaign played so far, as the batch fidelity's plan (see
        :attr:`twin.envs.campaign_env.CpsCampaignEnv.plan`)."""
        return replace(self.planner.plan, steps=tuple(self.steps), strategy="agent")

    def close(self) -> None:
        """Free the planner's campaign."""
        self.planner.close()

    # -- moves ---------------------------------------------------------------------------------
    def resolve(self, action: object) -> tuple[int, dict[str, Any] | None]:
        """The move to take for ``action`` (its fallback if it is forbidden), and the
        fallback's report (None when the move is allowed).

        Raises:
            ValueError: ``action`` is not in the action space
                (:meth:`twin.envs.moves.MoveLayout.check`), or it is forbidden and the
                environment is strict.
            RuntimeError: the campaign is over.
        """
        planner, layout = self.planner, self.settings.layout
        if planner.done:
            raise RuntimeError("the campaign is over: call reset()")
        action = layout.check(action)
        if planner.mask[action]:
            return action, None
        what = layout.describe(action)
        if self.settings.strict:
            raise ValueError(f"{what} (action {action}) is not allowed now (see action_masks())")
        taken = layout.fallback(action, planner.mask)
        self.fallbacks += 1
        return taken, {
            "requested": action,
            "taken": taken,
            "move": layout.describe(taken),
            "reason": f"{what} is not allowed now",
        }

    def apply(self, action: int) -> float:
        """Take an allowed move and execute its steps on the episode's batch; its reward."""
        assert self.batch is not None
        steps = self.planner.act(action)
        for step in steps:
            self.batch.step(step)
        return self.account(action, steps)

    def account(self, action: int, steps: tuple[Step, ...]) -> float:
        """The move ``action`` was taken and ``steps`` executed: its reward."""
        planner, batch, settings = self.planner, self.batch, self.settings
        assert batch is not None
        self.steps.extend(steps)
        self.moves.append(action)
        distance = float(batch.distance[self.row])
        time_s = planner.time
        predicted = self.mean_predicted_mm()
        if settings.reward_mode == "predicted":
            reward = (
                (self._predicted - predicted)
                - settings.cost_per_m * (distance - self._distance)
                - settings.cost_per_s * (time_s - self._time)
            )
        else:
            reward = -self.mean_true_mm() if planner.done else 0.0
        self._predicted, self._distance, self._time = predicted, distance, time_s
        return float(reward)

    def finish(
        self, action: int, reward: float, fallback: dict[str, Any] | None
    ) -> tuple[float, bool, dict[str, Any]]:
        """The reward, whether the campaign is over, and the info after the move
        ``action`` (the observation is built apart: a vector builds its episodes' at
        once)."""
        info = self.info()
        info["move"] = self.settings.layout.describe(action)
        if fallback is not None:
            info["fallback"] = fallback
        return reward, self.planner.done, info

    def info(self) -> dict[str, Any]:
        """What ``reset`` and ``step`` report besides the observation (see
        :mod:`twin.envs.campaign_env`)."""
        return {
            "camera_errors_mm": self.camera_errors_mm(),
            "parent_error_mm": self.parent_error_mm(),
            "distance_m": float(self.now().distance[self.row]),
            "time_s": self.planner.time,
            "action_mask": self.planner.mask.copy(),
            "decision": self.planner.decision,
            "fallbacks": self.fallbacks,
        }

    # -- what the campaign knows ---------------------------------------------------------------
    def now(self) -> Knowledge:
        """What the episode's batch knows now (every trial of it)."""
        if self._known is None:
            raise RuntimeError("call reset() first")
        return self._known.now()

    def camera_states(self) -> list[CameraState]:
        """What the campaign knows of each camera, in the site's order."""
        known, row = self.now(), self.row
        here = self.planner.here_camera()
        return [
            CameraState(
                bool(known.calibrated[row, j]),
                float(known.predicted[row, j]),
                float(known.calibration[row, j]),
                float(known.transfer_now[row, j]),
                np.asarray(cam.position, dtype=float),
                here == cam.name,
            )
            for j, cam in enumerate(self.scenario.cameras)
        ]

    def mean_predicted_mm(self) -> float:
        """The mean predicted world-frame camera error, mm (a camera not calibrated counts
        ``uncalibrated_error_mm``)."""
        known, row = self.now(), self.row
        if not known.calibrated.shape[1]:
            return 0.0
        errors = np.where(
            known.calibrated[row], 1e3 * known.predicted[row], self.settings.uncalibrated_error_mm
        )
        return float(np.mean(errors))

    def camera_errors_mm(self) -> dict[str, float]:
        """The true world-frame position error of each camera calibrated so far (the
        calibration delivered: of its visits, the one with the lowest predicted error), mm."""
        known, row = self.now(), self.row
        assert self._known is not None
        return {
            name: 1e3 * float(known.position_error[row, j])
            for j, name in enumerate(self._known.cameras)
            if known.calibrated[row, j]
        }

    def mean_true_mm(self) -> float:
        """The mean true world-frame camera position error, mm (a camera not calibrated
        counts ``uncalibrated_error_mm``)."""
        errors = self.camera_errors_mm()
        missing = self.settings.uncalibrated_error_mm
        return float(np.mean([errors.get(c.name, missing) for c in self.scenario.cameras]))

    def parent_error_mm(self) -> float:
        """The trial's parent position error at its last fix, mm."""
        return 1e3 * float(self.now().parent_error[self.row])

    # -- what it observes ----------------------------------------------------------------------
    def stations(self) -> Stations:
        """The calibration stations, in the order of ``go_to``."""
        planner = self.planner
        names = [c.name for c in self.scenario.cameras]
        placed = [planner.stations[name] for name in planner.order]
        here = planner.here()
        return Stations(
            np.array([names.index(str(st.camera)) for st in placed], dtype=np.int64),
            np.array([st.xy for st in placed]).reshape(-1, 2),
            np.array([planner.route_distance(st) for st in placed]),
            planner.order.index(here) if here in planner.order else None,
        )

    def where(self) -> tuple[str | None, NDArray[np.float64], int, Stations, float]:
        """Where the episode's campaign stands: its decision, the station it travels to
        ((2,), NaN between travels), the index of the camera whose station it stands at
        (-1: none), the stations, its time (s)."""
        planner = self.planner
        goal = planner.goal_station
        here = planner.here_camera()
        names = [c.name for c in self.scenario.cameras]
        return (
            planner.decision,
            np.full(2, np.nan) if goal is None or planner.decision != LEG else goal.xy,
            -1 if here is None else names.index(here),
            self.stations(),
            planner.time,
        )

    def observations(
        self, rows: list[int], episodes: list[Episode] | None = None
    ) -> dict[str, NDArray[np.float32]]:
        """The observations of ``rows`` of the episode's batch, each entry (R, ...): the
        episode's own and those of other episodes of its site whose trials are rows of the
        same batch (``episodes``, one a row; default this one for every row)."""
        known = self.now()
        assert self._known is not None
        where = [e.where() for e in episodes] if episodes else [self.where()] * len(rows)
        distance = known.distance[rows]
        stations = where[0][3]
        return build_observations(
            decision=[w[0] for w in where],
            parent_xy=known.parent_xy[rows],
            parent_yaw=known.parent_yaw[rows],
            parent_covariance=known.parent_covariance[rows],
            children_pose=known.children[rows],
            travel=np.column_stack(
                [distance, self.planner.budget_m - distance, np.array([w[4] for w in where])]
            ),
            goal_xy=np.array([w[1] for w in where]).reshape(len(rows), 2),
            camera_xyz=self._known.positions,
            calibrated=known.calibrated[rows],
            predicted_error=known.predicted[rows],
            transfer_now=known.transfer_now[rows],
            here_camera=np.array([w[2] for w in where], dtype=np.int64),
            max_cameras=self.settings.max_cameras,
            stations=Stations(
                stations.camera,
                stations.xy,
                np.array([w[3].route_distance for w in where]).reshape(len(rows), -1),
                np.array([-1 if w[3].here is None else w[3].here for w in where], dtype=np.int64),
            ),
            max_stations=self.settings.layout.max_stations,
            free_space=self.free_space.rays(known.parent_xy[rows], known.parent_yaw[rows]),
            site=self.site_scale,
            budget_m=self.planner.budget_m,
        )

    def observation(self) -> dict[str, NDArray[np.float32]]:
        """The episode's own observation."""
        return {k: v[0] for k, v in self.observations([self.row]).items()}
