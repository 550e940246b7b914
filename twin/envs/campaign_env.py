"""``camnet/CpsCampaign-v0``: the calibration campaign as a Gymnasium environment whose agent
chooses the robot group's moves.

An episode is one campaign on a site: a scenario file, or a random site drawn from the
reset seed (:mod:`twin.envs.sites`). A step is one decision of the campaign's strategy
interface (:mod:`twin.campaign.strategy`), taken by the agent (:mod:`twin.envs.moves`):
the formation and length of the next CPS leg; between travels, calibrate the camera whose
station the group stands at, travel to a camera's station, return to the start, or end.
The campaign itself runs the decisions without noise (:mod:`twin.envs.planner`), and one
trial of the batch fidelity (:class:`twin.batch.execute.BatchRun`) executes its steps with
the scenario's noise: the estimates, covariances and errors the agent observes and is
rewarded by are that trial's.

Action masks: ``info["action_mask"]`` and :meth:`CpsCampaignEnv.action_masks` (sb3-contrib's
MaskablePPO convention). A forbidden move runs :meth:`twin.envs.moves.MoveLayout.fallback`
(reported in ``info["fallback"]``); with ``strict=True`` it raises ``ValueError``. An action
outside the action space (a value out of range, a bool, a float) always raises
``ValueError``.

Rewards (``reward_mode``):

- ``predicted`` (default): the decrease of the mean predicted world-frame camera error (mm;
  a camera not calibrated counts ``uncalibrated_error_mm``) minus ``cost_per_m`` per metre
  travelled and ``cost_per_s`` per second of campaign time;
- ``truth``: 0 until the campaign ends, then minus the mean true world-frame camera
  position error, mm (a camera not calibrated counts ``uncalibrated_error_mm``).

``info`` always carries ``camera_errors_mm`` (true, per camera calibrated so far),
``parent_error_mm``, ``distance_m``, ``time_s``, ``action_mask`` and ``decision``, so that
any reward can be computed afterwards.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from numpy.typing import NDArray

from twin.batch.execute import BatchRun
from twin.batch.plan import BatchPlan, Calibrate, Step
from twin.envs.free_space import FreeSpace
from twin.envs.knowledge import BatchKnowledge, Knowledge
from twin.envs.moves import MoveLayout
from twin.envs.observation import (
    CameraState,
    Stations,
    build_observations,
    observation_space,
)
from twin.envs.planner import CampaignPlanner, EpisodePlanner
from twin.envs.sites import random_site
from twin.envs.stands import StandPlanner, rounded_std
from twin.scenario import load_scenario
from twin.scenario.schema import Scenario

__all__ = ["PLANNERS", "RESET_OPTIONS", "REWARD_MODES", "CpsCampaignEnv", "check_options"]

REWARD_MODES = ("predicted", "truth")
"""The rewards an environment can give (see the module)."""

BUDGET_FACTOR = 2.5
"""Default travel budget, in lengths of the site's route."""

_EPISODE_STATE = frozenset(
    {
        "planner",
        "batch",
        "_free",
        "_free_for",
        "_episode",
        "_fallbacks",
        "_time",
        "_distance",
        "_predicted",
        "_steps",
        "_row",
        "_known",
    }
)
"""What pickling leaves out and rebuilds by replaying the episode's moves."""

PLANNERS = ("campaign", "stands")
"""How an environment plays its campaign: ``campaign`` runs the campaign itself for each
new sequence of moves (:mod:`twin.envs.planner`); ``stands`` reads the moves from a table of
the site, for speed (:mod:`twin.envs.stands`, with what it leaves out)."""

RANDOM = "random"
"""``scenario`` for a random site at each reset."""

RESET_OPTIONS = ("scenario",)
"""The keys ``reset(options=...)`` knows (see :meth:`CpsCampaignEnv.reset`)."""


def _scenario(spec: str | Path | Scenario | None) -> Scenario | None:
    """A scenario from a path or a scenario; None for random sites.

    Raises:
        ValueError: ``spec`` is none of these.
        ScenarioError: the file is not a valid scenario.
    """
    if spec is None or (isinstance(spec, str) and spec == RANDOM):
        return None
    if isinstance(spec, Scenario):
        return spec
    if not isinstance(spec, (str, Path)):
        raise ValueError(
            f"scenario {spec!r}: expected a scenario file (str or Path), a Scenario, "
            f"{RANDOM!r} or None, got {type(spec).__name__}"
        )
    return load_scenario(spec)


def check_options(options: object) -> dict[str, Any]:
    """The options of a reset, checked: None or a mapping whose keys are
    :data:`RESET_OPTIONS`; its scenario read (a :class:`Scenario`, or None for a random
    site).

    Raises:
        ValueError: ``options`` is not a mapping, or has a key it does not know, or its
            scenario is not one.
        ScenarioError: its scenario file is not a valid scenario.
    """
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise ValueError(
            f"reset options {options!r}: expected a dict of options by name "
            f"({', '.join(RESET_OPTIONS)}) or None, got {type(options).__name__}"
        )
    for key in options:
        if key not in RESET_OPTIONS:
            raise ValueError(
                f"unknown reset option {key!r}; known options: {', '.join(RESET_OPTIONS)}"
            )
    checked = dict(options)
    if "scenario" in checked:
        checked["scenario"] = _scenario(checked["scenario"])
    return checked


class CpsCampaignEnv(gym.Env):
    """The campaign as an environment (see the module).

    Args:
        scenario: a scenario file or :class:`Scenario`; None or ``"random"``: a random
            site at every reset, drawn from its seed.
        render_mode: None or ``rgb_array`` (a top view of the site).
        reward_mode: ``predicted`` or ``truth``.
        strict: raise on a forbidden move instead of running its fallback.
        max_cameras: cameras the observation has room for.
        max_stations: calibration stations the observation and the moves have room for.
        budget_m: the parent's travel allowed per episode, m (default
            :data:`BUDGET_FACTOR` times the route's length).
        cost_per_m, cost_per_s: the predicted reward's cost of travel (mm of mean
            camera error per metre) and of time (per second).
        uncalibrated_error_mm: the error counted for a camera not calibrated, mm.
        layout: the moves (default :class:`MoveLayout` with ``max_stations``).
        planner: one of :data:`PLANNERS`: ``campaign`` (default: the campaign itself) or
            ``stands`` (a table of the site: fast enough for random moves).
    """

    metadata = {  # noqa: RUF012  (Gymnasium's convention: a class attribute)
        "render_modes": ["rgb_array"],
        "render_fps": 2,
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        scenario: str | Path | Scenario | None = None,
        render_mode: str | None = None,
        reward_mode: str = "predicted",
        strict: bool = False,
        max_cameras: int = 8,
        max_stations: int = 12,
        budget_m: float | None = None,
        cost_per_m: float = 0.5,
        cost_per_s: float = 0.0,
        uncalibrated_error_mm: float = 1000.0,
        layout: MoveLayout | None = None,
        planner: str = "campaign",
    ) -> None:
        if planner not in PLANNERS:
            raise ValueError(f"planner must be one of {PLANNERS}, got {planner!r}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be one of {self.metadata['render_modes']} or None, "
                f"got {render_mode!r}"
            )
        if reward_mode not in REWARD_MODES:
            raise ValueError(f"reward_mode must be one of {REWARD_MODES}, got {reward_mode!r}")
        if budget_m is not None and not budget_m > 0:
            raise ValueError(f"budget_m must be > 0 m, got {budget_m}")
        costs = (
            ("cost_per_m", cost_per_m),
            ("cost_per_s", cost_per_s),
            ("uncalibrated_error_mm", uncalibrated_error_mm),
        )
        for name, value in costs:
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {value}")
        if max_cameras < 1:
            raise ValueError(f"max_cameras must be >= 1, got {max_cameras}")
        self.layout = layout if layout is not None else MoveLayout(max_stations=max_stations)
        self.planner_name = planner
        self.max_cameras = max_cameras
        self.default_scenario = _scenario(scenario)
        self.render_mode = render_mode
        self.reward_mode = reward_mode
        self.strict = strict
        self.budget_m = budget_m
        self.cost_per_m = cost_per_m
        self.cost_per_s = cost_per_s
        self.uncalibrated_error_mm = uncalibrated_error_mm
        self.action_space = spaces.Discrete(self.layout.size)
        self.observation_space = observation_space(max_cameras, self.layout.max_stations)
        self.planner: EpisodePlanner | None = None
        self.batch: BatchRun | None = None
        self.scenario: Scenario | None = None
        self._free: FreeSpace | None = None
        self._free_for: Scenario | None = None
        self._episode: dict[str, Any] = {}
        self._steps: list[Step] = []
        self._fallbacks = 0
        self._row = 0  # the episode's trial in self.batch
        self._known: BatchKnowledge | None = None  # what self.batch knows

    # -- episodes ---------------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, NDArray[np.float64]], dict[str, Any]]:
        """Start a campaign. ``options["scenario"]``: a scenario file, a
        :class:`Scenario` or ``"random"`` for this episode (default: the environment's).

        Raises:
            ValueError: ``options`` is not a dict, or has a key other than
                :data:`RESET_OPTIONS`, or its scenario is not one.
        """
        options = check_options(options)
        super().reset(seed=seed)
        scenario, trial_seed = self._draw(options)
        self._start_episode(scenario, trial_seed)
        return self._observation(), self._info()

    # The episode's parts, which a vector of environments (twin.envs.vector) runs for many
    # episodes at once: draw the site and the noise seed, prepare the campaign, attach the
    # trials that execute it; then per move resolve it, take it, execute it, account for it.
    def _draw(self, options: dict[str, Any] | None) -> tuple[Scenario, int]:
        """The episode's site and noise seed, from the generator (after seeding it);
        ``options`` as :func:`check_options` returns them."""
        options = options or {}
        scenario = options.get("scenario", self.default_scenario)
        if scenario is None:
            scenario = random_site(self.np_random)
        return scenario, int(self.np_random.integers(2**62))

    def _start_episode(self, scenario: Scenario, trial_seed: int) -> None:
        steps = self._prepare(scenario, trial_seed)
        assert self.planner is not None
        batch = BatchRun(self.planner.plan, [trial_seed])
        for step in steps:
            batch.step(step)
        self._attach(batch, 0, steps)

    def _prepare(self, scenario: Scenario, trial_seed: int) -> tuple[Step, ...]:
        """Start the episode's campaign; the plan's steps before the first decision."""
        if len(scenario.cameras) > self.max_cameras:
            raise ValueError(
                f"{scenario.name}: {len(scenario.cameras)} cameras, more than max_cameras = "
                f"{self.max_cameras}"
            )
        route = np.asarray(scenario.route.waypoints, dtype=float)
        budget = self.budget_m
        if budget is None:
            budget = BUDGET_FACTOR * float(np.linalg.norm(np.diff(route, axis=0), axis=1).sum())
        planner: EpisodePlanner
        if self.planner_name == "stands":
            planner = StandPlanner(scenario, self.layout, budget)  # may refuse the site
            planner.parent_std = self._parent_std
        else:
            planner = CampaignPlanner(scenario, self.layout, budget)  # may refuse the site
        self._close_episode()
        self.planner = planner
        self.scenario = scenario
        if self._free_for is not scenario:
            self._free, self._free_for = FreeSpace(scenario.space), scenario
        self._episode = {"scenario": scenario, "trial_seed": trial_seed, "moves": []}
        return self.planner.take_pending()

    def _attach(
        self,
        batch: BatchRun,
        row: int,
        steps: tuple[Step, ...],
        known: BatchKnowledge | None = None,
    ) -> None:
        """The episode's trial is row ``row`` of ``batch``, which has executed ``steps``
        (``known``: the batch's knowledge, shared with the other episodes of the batch)."""
        assert self.planner is not None
        self._join(batch, row, known)
        self._steps = list(steps)
        self._time = self.planner.time
        self._distance = 0.0
        self._predicted = self._mean_predicted_mm()
        self._fallbacks = 0

    def _join(self, batch: BatchRun, row: int, known: BatchKnowledge | None = None) -> None:
        """The episode's trial is now row ``row`` of ``batch``."""
        assert self.scenario is not None
        if known is None:
            known = self.knowledge_of(batch)
        self.batch, self._row, self._known = batch, row, known

    def knowledge_of(self, batch: BatchRun) -> BatchKnowledge:
        """What a batch of the episode's campaign knows (see :mod:`twin.envs.knowledge`)."""
        assert self.scenario is not None
        cameras = self.scenario.cameras
        return BatchKnowledge(
            batch, tuple(c.name for c in cameras), np.array([c.position for c in cameras])
        )

    def step(
        self, action: int
    ) -> tuple[dict[str, NDArray[np.float64]], float, bool, bool, dict[str, Any]]:
        """Take a move (see :mod:`twin.envs.moves`).

        Raises:
            ValueError: ``action`` is not in the action space (an int in
                ``0 .. action_space.n - 1``; a forbidden move inside it runs its fallback,
                or raises if the environment is strict).
        """
        action, fallback = self._resolve(action)
        reward = self._apply(action)
        return self._outcome(action, reward, fallback)

    def _resolve(self, action: object) -> tuple[int, dict[str, Any] | None]:
        """The move to take for ``action`` (its fallback if it is forbidden), and the
        fallback's report (None when the move is allowed).

        Raises:
            ValueError: ``action`` is not in the action space
                (:meth:`twin.envs.moves.MoveLayout.check`), or it is forbidden and the
                environment is strict.
            RuntimeError: no episode, or the campaign is over.
        """
        planner = self.planner
        if planner is None:
            raise RuntimeError("call reset() before step()")
        if planner.done:
            raise RuntimeError("the campaign is over: call reset()")
        action = self.layout.check(action)
        if planner.mask[action]:
            return action, None
        what = self.layout.describe(action)
        if self.strict:
            raise ValueError(f"{what} (action {action}) is not allowed now (see action_masks())")
        taken = self.layout.fallback(action, planner.mask)
        self._fallbacks += 1
        return taken, {
            "requested": action,
            "taken": taken,
            "move": self.layout.describe(taken),
            "reason": f"{what} is not allowed now",
        }

    def _outcome(
        self, action: int, reward: float, fallback: dict[str, Any] | None
    ) -> tuple[dict[str, NDArray[np.float64]], float, bool, bool, dict[str, Any]]:
        """What ``step`` returns after the move ``action``."""
        reward, terminated, info = self._finish(action, reward, fallback)
        return self._observation(), reward, terminated, False, info

    def _finish(
        self, action: int, reward: float, fallback: dict[str, Any] | None
    ) -> tuple[float, bool, dict[str, Any]]:
        """The reward, whether the campaign is over, and the info after the move
        ``action`` (the observation is built apart: a vector builds its episodes' at
        once)."""
        assert self.planner is not None
        info = self._info()
        info["move"] = self.layout.describe(action)
        if fallback is not None:
            info["fallback"] = fallback
        return reward, self.planner.done, info

    def _apply(self, action: int) -> float:
        """Take an allowed move and execute its steps; its reward."""
        assert self.planner is not None
        assert self.batch is not None
        steps = self.planner.act(action)
        for step in steps:
            self.batch.step(step)
        return self._account(action, steps)

    def _account(self, action: int, steps: tuple[Step, ...]) -> float:
        """The move ``action`` was taken and ``steps`` executed: its reward."""
        planner, batch = self.planner, self.batch
        assert planner is not None
        assert batch is not None
        self._steps.extend(steps)
        self._episode["moves"].append(action)
        distance = float(batch.distance[self._row])
        time_s = planner.time
        predicted = self._mean_predicted_mm()
        if self.reward_mode == "predicted":
            reward = (
                (self._predicted - predicted)
                - self.cost_per_m * (distance - self._distance)
                - self.cost_per_s * (time_s - self._time)
            )
        else:
            reward = -self._mean_true_mm() if planner.done else 0.0
        self._predicted, self._distance, self._time = predicted, distance, time_s
        return float(reward)

    # -- pickling: the settings, the generator and the episode's moves, replayed -----------------
    def __getstate__(self) -> dict[str, Any]:
        state = {k: v for k, v in self.__dict__.items() if k not in _EPISODE_STATE}
        state["_episode"] = getattr(self, "_episode", None)
        state["_fallbacks"] = getattr(self, "_fallbacks", 0)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        episode, fallbacks = state.pop("_episode"), state.pop("_fallbacks")
        self.__dict__.update(state)
        self.planner, self.batch, self._free, self._free_for = None, None, None, None
        self._known = None
        if episode:
            self._start_episode(episode["scenario"], episode["trial_seed"])
            for action in episode["moves"]:
                self._apply(action)
            self._fallbacks = fallbacks

    @property
    def plan(self) -> BatchPlan:
        """The campaign the episode has played so far, as the batch fidelity's plan: run it
        for many trials with :class:`twin.batch.execute.BatchRun` (every trial of a policy
        whose moves do not depend on the noise at once). Its ``planned_visits`` are the
        visits the campaign calibrated (a visit it gave up is not in the plan's steps)."""
        if self.planner is None:
            raise RuntimeError("call reset() before reading the plan")
        visits = tuple((s.camera, s.visit) for s in self._steps if isinstance(s, Calibrate))
        return replace(
            self.planner.plan, steps=tuple(self._steps), strategy="agent", planned_visits=visits
        )

    @property
    def trial_seed(self) -> int:
        """The episode's noise seed (drawn from the reset seed): its trial in a batch."""
        if not self._episode:
            raise RuntimeError("call reset() before reading the trial seed")
        return int(self._episode["trial_seed"])

    def action_masks(self) -> NDArray[np.bool_]:
        """(n,) the moves allowed now (sb3-contrib's MaskablePPO reads this)."""
        if self.planner is None:
            raise RuntimeError("call reset() before action_masks()")
        return self.planner.mask.copy()

    def close(self) -> None:
        self._close_episode()
        self._episode = {}  # a closed environment pickles without its episode

    def _close_episode(self) -> None:
        if self.planner is not None:
            self.planner.close()
        self.planner, self.batch, self._known = None, None, None

    # -- what the campaign knows -------------------------------------------------------------------
    def _now(self) -> Knowledge:
        """What the episode's batch knows now (every trial of it)."""
        if self._known is None:
            raise RuntimeError("call reset() first")
        return self._known.now()

    def camera_states(self) -> list[CameraState]:
        """What the campaign knows of each camera, in the site's order."""
        assert self.planner is not None
        assert self.scenario is not None
        known, row = self._now(), self._row
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

    def _parent_std(self) -> float:
        """The trial's parent horizontal standard deviation, rounded (see
        :func:`twin.envs.stands.rounded_std`), m."""
        return rounded_std(self._now().parent_covariance[self._row])

    def _mean_predicted_mm(self) -> float:
        known, row = self._now(), self._row
        if not known.calibrated.shape[1]:
            return 0.0
        errors = np.where(
            known.calibrated[row], 1e3 * known.predicted[row], self.uncalibrated_error_mm
        )
        return float(np.mean(errors))

    def camera_errors_mm(self) -> dict[str, float]:
        """The true world-frame position error of each camera calibrated so far (the
        calibration delivered: of its visits, the one with the lowest predicted error), mm."""
        known, row = self._now(), self._row
        assert self._known is not None
        return {
            name: 1e3 * float(known.position_error[row, j])
            for j, name in enumerate(self._known.cameras)
            if known.calibrated[row, j]
        }

    def _mean_true_mm(self) -> float:
        assert self.scenario is not None
        errors = self.camera_errors_mm()
        return float(
            np.mean([errors.get(c.name, self.uncalibrated_error_mm) for c in self.scenario.cameras])
        )

    def parent_error_mm(self) -> float:
        """The trial's parent position error at its last fix, mm."""
        return 1e3 * float(self._now().parent_error[self._row])

    def _stations(self) -> Stations:
        """The calibration stations, in the order of ``go_to``."""
        planner, scenario = self.planner, self.scenario
        assert planner is not None
        assert scenario is not None
        names = [c.name for c in scenario.cameras]
        placed = [planner.stations[name] for name in planner.order]
        here = planner.here()
        return Stations(
            np.array([names.index(str(st.camera)) for st in placed], dtype=np.int64),
            np.array([st.xy for st in placed]).reshape(-1, 2),
            np.array([planner.route_distance(st) for st in placed]),
            planner.order.index(here) if here in planner.order else None,
        )

    def _where(self) -> tuple[str | None, NDArray[np.float64], int, Stations, float]:
        """Where the episode's campaign stands: its decision, the station it travels to
        ((2,), NaN between travels), the index of the camera whose station it stands at
        (-1: none), the stations, its time (s)."""
        planner, scenario = self.planner, self.scenario
        assert planner is not None
        assert scenario is not None
        goal = planner.goal_station
        here = planner.here_camera()
        names = [c.name for c in scenario.cameras]
        return (
            planner.decision,
            np.full(2, np.nan) if goal is None or planner.decision != "leg" else goal.xy,
            -1 if here is None else names.index(here),
            self._stations(),
            planner.time,
        )

    def observations(
        self, rows: list[int], episodes: list[CpsCampaignEnv] | None = None
    ) -> dict[str, NDArray[np.float64]]:
        """The observations of ``rows`` of the episode's batch, each entry (R, ...): the
        episode's own and those of other episodes of its site whose trials are rows of the
        same batch (``episodes``, one a row; default this one for every row)."""
        planner = self.planner
        assert planner is not None
        assert self._free is not None
        known = self._now()
        assert self._known is not None
        where = [e._where() for e in episodes] if episodes else [self._where()] * len(rows)
        distance = known.distance[rows]
        stations = where[0][3]
        return build_observations(
            decision=[w[0] for w in where],
            parent_xy=known.parent_xy[rows],
            parent_yaw=known.parent_yaw[rows],
            parent_covariance=known.parent_covariance[rows],
            children_pose=known.children[rows],
            travel=np.column_stack(
                [distance, planner.budget_m - distance, np.array([w[4] for w in where])]
            ),
            goal_xy=np.array([w[1] for w in where]).reshape(len(rows), 2),
            camera_xyz=self._known.positions,
            calibrated=known.calibrated[rows],
            predicted_error=known.predicted[rows],
            transfer_now=known.transfer_now[rows],
            here_camera=np.array([w[2] for w in where], dtype=np.int64),
            max_cameras=self.max_cameras,
            stations=Stations(
                stations.camera,
                stations.xy,
                np.array([w[3].route_distance for w in where]).reshape(len(rows), -1),
                np.array([-1 if w[3].here is None else w[3].here for w in where], dtype=np.int64),
            ),
            max_stations=self.layout.max_stations,
            free_space=self._free.rays(known.parent_xy[rows], known.parent_yaw[rows]),
        )

    def _observation(self) -> dict[str, NDArray[np.float64]]:
        return {k: v[0] for k, v in self.observations([self._row]).items()}

    def _info(self) -> dict[str, Any]:
        assert self.planner is not None
        return {
            "camera_errors_mm": self.camera_errors_mm(),
            "parent_error_mm": self.parent_error_mm(),
            "distance_m": float(self._now().distance[self._row]),
            "time_s": self.planner.time,
            "action_mask": self.planner.mask.copy(),
            "decision": self.planner.decision,
            "fallbacks": self._fallbacks,
        }

    # -- rendering ---------------------------------------------------------------------------------
    def render(self) -> NDArray[np.uint8] | None:
        """A top view (``rgb_array``): the site, the cameras and their views, the robots,
        the parent's track and its covariance ellipse (x 100)."""
        if self.render_mode is None:
            return None
        if self.batch is None or self.scenario is None:
            raise RuntimeError("call reset() before render()")
        from twin.envs.render import top_view_rgb

        track = self.batch.track(self._row)
        return top_view_rgb(self.scenario, self.batch, track, self.camera_errors_mm(), self._row)
