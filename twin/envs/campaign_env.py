"""``camnet/CpsCampaign-v0``: the calibration campaign as a Gymnasium environment whose agent
chooses the robot group's moves.

An episode is one campaign on a site: a scenario file, or a random site drawn from the
reset seed (:mod:`twin.envs.sites`). A step is one decision of the campaign's strategy
interface (:mod:`twin.campaign.strategy`), taken by the agent (:mod:`twin.envs.moves`):
the formation and length of the next CPS leg; between travels, calibrate the camera whose
station the group stands at, travel to a camera's station, return to the start, or end.
A table of the site (the default ``stands`` planner, :mod:`twin.envs.stands`) or the
campaign itself (``campaign``, :mod:`twin.envs.planner`) runs the decisions without noise,
and one trial of the batch fidelity (:class:`twin.batch.execute.BatchRun`) executes its
steps with the scenario's noise: the estimates, covariances and errors the agent observes and is
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

import copy
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from numpy.typing import NDArray

from twin.batch.execute import BatchRun
from twin.batch.steps import BatchPlan
from twin.envs.episode import Episode, EpisodePlanner, EpisodeSettings
from twin.envs.free_space import FreeSpace
from twin.envs.moves import MoveLayout
from twin.envs.observation import (
    CameraState,
    observation_space,
)
from twin.envs.planner import CampaignPlanner
from twin.envs.scenario_paths import resolve_scenario_path
from twin.envs.sites import random_site
from twin.envs.stands import StandPlanner, rounded_std
from twin.scenario import load_scenario
from twin.scenario.schema import Scenario

__all__ = [
    "COST_PER_M",
    "COST_PER_S",
    "PLANNERS",
    "RESET_OPTIONS",
    "REWARD_MODES",
    "CpsCampaignEnv",
    "check_options",
]

REWARD_MODES = ("predicted", "truth")
"""The rewards an environment can give (see the module)."""

COST_PER_S = 1e-3
"""Default cost of campaign time, mm of mean camera error per second: an hour costs 3.6 mm,
about what a few mm of a camera's world-frame error are worth (a calibrated camera is
worth ``uncalibrated_error_mm`` less its error, some 20 mm, to the sum; the hall's
campaigns take a few minutes). Small beside the reward of calibrating a camera or the cost
of travel (:data:`COST_PER_M`), it makes a longer campaign pay for itself: of two
campaigns with the same errors, the shorter one earns more."""

COST_PER_M = 0.5
"""Default cost of the parent's travel, mm of mean camera error per metre."""

BUDGET_FACTOR = 2.5
"""Default travel budget, in lengths of the site's route."""

_EPISODE_STATE = frozenset({"episode", "_free", "_free_for"})
"""What pickling leaves out and rebuilds by replaying the episode's moves."""

PLANNERS = ("campaign", "stands")
"""How an environment plays its campaign: ``campaign`` runs the campaign itself for each
new sequence of moves (:mod:`twin.envs.planner`: faithful, for evaluation); ``stands`` (the
default, for training) reads the moves from a table of the site, for speed
(:mod:`twin.envs.stands`, with what it leaves out)."""

RANDOM = "random"
"""``scenario`` for a random site at each reset."""

RESET_OPTIONS = ("scenario",)
"""The keys ``reset(options=...)`` knows (see :meth:`CpsCampaignEnv.reset`)."""


def _scenario(spec: str | Path | Scenario | None, near: Scenario | None = None) -> Scenario | None:
    """A scenario from a path or a scenario; None for random sites. A relative path is
    found as :func:`twin.envs.scenario_paths.resolve_scenario_path` says (``near``: the
    environment's own scenario, whose folder is tried).

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
    return load_scenario(resolve_scenario_path(spec, near.source if near is not None else None))


def check_options(options: object, near: Scenario | None = None) -> dict[str, Any]:
    """The options of a reset, checked: None or a mapping whose keys are
    :data:`RESET_OPTIONS`; its scenario read (a :class:`Scenario`, or None for a random
    site; a relative path is also tried next to ``near``'s file).

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
        checked["scenario"] = _scenario(checked["scenario"], near)
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
            camera error per metre, default :data:`COST_PER_M`) and of campaign time (per
            second, default :data:`COST_PER_S`).
        uncalibrated_error_mm: the error counted for a camera not calibrated, mm.
        layout: the moves (default :class:`MoveLayout` with ``max_stations``).
        planner: one of :data:`PLANNERS`: ``stands`` (default: a table of the site, fast
            enough for training with random moves, its tables kept on disk by
            :mod:`twin.envs.stand_cache`) or ``campaign`` (the campaign itself: the faithful
            one, which ``twin strategies`` evaluates with by default).
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
        cost_per_m: float = COST_PER_M,
        cost_per_s: float = COST_PER_S,
        uncalibrated_error_mm: float = 1000.0,
        layout: MoveLayout | None = None,
        planner: str = "stands",
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
        self.episode: Episode | None = None
        self._free: FreeSpace | None = None  # the free space of the last site
        self._free_for: Scenario | None = None

    # -- episodes ---------------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, NDArray[np.float32]], dict[str, Any]]:
        """Start a campaign. ``options["scenario"]``: a scenario file, a
        :class:`Scenario` or ``"random"`` for this episode (default: the environment's).

        Raises:
            ValueError: ``options`` is not a dict, or has a key other than
                :data:`RESET_OPTIONS`, or its scenario is not one.
        """
        options = check_options(options, self.default_scenario)
        super().reset(seed=seed)
        episode = self._start_episode(*self.draw(options))
        return episode.observation(), episode.info()

    # An episode's parts, which a vector of environments (twin.envs.vector) runs for many
    # episodes at once: draw the site and the noise seed, prepare the episode, attach the
    # trial that executes it; then per move resolve it, take it, execute it, account for it
    # (twin.envs.episode.Episode).
    def draw(self, options: dict[str, Any] | None) -> tuple[Scenario, int]:
        """The next episode's site and noise seed, from the generator (after seeding it);
        ``options`` as :func:`check_options` returns them."""
        options = options or {}
        scenario = options.get("scenario", self.default_scenario)
        if scenario is None:
            scenario = random_site(self.np_random)
        return scenario, int(self.np_random.integers(2**62))

    def prepare(self, scenario: Scenario, trial_seed: int) -> Episode:
        """Start the episode's campaign (the environment's episode from now on); its trial is
        yet to run the start's steps (:attr:`Episode.start_steps`) and be attached
        (:meth:`Episode.attach`).

        Raises:
            ValueError: the site has more cameras or stations than the environment has room
                for (the current episode is kept).
        """
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
        else:
            planner = CampaignPlanner(scenario, self.layout, budget)  # may refuse the site
        self._close_episode()
        if self._free_for is not scenario:
            self._free, self._free_for = FreeSpace(scenario.space), scenario
        assert self._free is not None
        settings = EpisodeSettings(
            self.layout,
            self.strict,
            self.reward_mode,
            self.cost_per_m,
            self.cost_per_s,
            self.uncalibrated_error_mm,
            self.max_cameras,
        )
        episode = self.episode = Episode(scenario, trial_seed, planner, self._free, settings)
        if isinstance(planner, StandPlanner):
            planner.parent_std = lambda: rounded_std(episode.now().parent_covariance[episode.row])
        return episode

    def next_trial_seeds(self, count: int) -> list[int]:
        """The noise seeds of the next ``count`` episodes if the environment resets by itself
        on the same site (none where the next site is drawn anew), left in its generator."""
        if self.default_scenario is None or self.scenario is not self.default_scenario:
            return []
        saved = self._np_random
        self._np_random = copy.deepcopy(saved)  # the draws of the next resets, not taken
        try:
            return [self.draw(None)[1] for _ in range(count)]
        finally:
            self._np_random = saved

    def _start_episode(self, scenario: Scenario, trial_seed: int) -> Episode:
        """Prepare an episode whose trial runs alone (a batch of one)."""
        episode = self.prepare(scenario, trial_seed)
        batch = BatchRun(episode.planner.plan, [trial_seed])
        for step in episode.start_steps:
            batch.step(step)
        episode.attach(batch, 0, episode.start_steps, None)
        return episode

    def step(
        self, action: int
    ) -> tuple[dict[str, NDArray[np.float32]], float, bool, bool, dict[str, Any]]:
        """Take a move (see :mod:`twin.envs.moves`).

        Raises:
            ValueError: ``action`` is not in the action space (an int in
                ``0 .. action_space.n - 1``; a forbidden move inside it runs its fallback,
                or raises if the environment is strict).
        """
        episode = self.episode
        if episode is None:
            raise RuntimeError("call reset() before step()")
        action, fallback = episode.resolve(action)
        reward = episode.apply(action)
        reward, terminated, info = episode.finish(action, reward, fallback)
        return episode.observation(), reward, terminated, False, info

    # -- pickling: the settings, the generator and the episode's moves, replayed -----------------
    def __getstate__(self) -> dict[str, Any]:
        state = {k: v for k, v in self.__dict__.items() if k not in _EPISODE_STATE}
        episode = self.__dict__.get("episode")
        state["_replay"] = (
            None
            if episode is None
            else (episode.scenario, episode.trial_seed, list(episode.moves), episode.fallbacks)
        )
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        replay = state.pop("_replay")
        self.__dict__.update(state)
        self.episode, self._free, self._free_for = None, None, None
        if replay is not None:
            scenario, trial_seed, moves, fallbacks = replay
            episode = self._start_episode(scenario, trial_seed)
            for action in moves:
                episode.apply(action)
            episode.fallbacks = fallbacks

    # -- the episode ------------------------------------------------------------------------------
    def _current(self, what: str) -> Episode:
        """The episode; RuntimeError naming ``what`` was asked before the first reset."""
        if self.episode is None:
            raise RuntimeError(f"call reset() before {what}")
        return self.episode

    @property
    def planner(self) -> EpisodePlanner | None:
        """The episode's campaign (None before the first reset)."""
        return None if self.episode is None else self.episode.planner

    @property
    def batch(self) -> BatchRun | None:
        """The batch whose row :attr:`Episode.row` is the episode's trial."""
        return None if self.episode is None else self.episode.batch

    @property
    def scenario(self) -> Scenario | None:
        """The episode's site (None before the first reset)."""
        return None if self.episode is None else self.episode.scenario

    @property
    def plan(self) -> BatchPlan:
        """The campaign the episode has played so far, as the batch fidelity's plan: run it
        for many trials with :class:`twin.batch.execute.BatchRun` (every trial of a policy
        whose moves do not depend on the noise at once). A visit the campaign gave up is
        not in the plan's steps."""
        return self._current("reading the plan").plan

    @property
    def trial_seed(self) -> int:
        """The episode's noise seed (drawn from the reset seed): its trial in a batch."""
        return self._current("reading the trial seed").trial_seed

    def action_masks(self) -> NDArray[np.bool_]:
        """(n,) the moves allowed now (sb3-contrib's MaskablePPO reads this)."""
        return self._current("action_masks()").planner.mask.copy()

    def close(self) -> None:
        self._close_episode()  # a closed environment pickles without its episode

    def _close_episode(self) -> None:
        if self.episode is not None:
            self.episode.close()
        self.episode = None

    def camera_states(self) -> list[CameraState]:
        """What the campaign knows of each camera, in the site's order."""
        return self._current("camera_states()").camera_states()

    def camera_errors_mm(self) -> dict[str, float]:
        """The true world-frame position error of each camera calibrated so far (the
        calibration delivered: of its visits, the one with the lowest predicted error), mm."""
        return self._current("camera_errors_mm()").camera_errors_mm()

    def parent_error_mm(self) -> float:
        """The trial's parent position error at its last fix, mm."""
        return self._current("parent_error_mm()").parent_error_mm()

    # -- rendering ---------------------------------------------------------------------------------
    def render(self) -> NDArray[np.uint8] | None:
        """A top view (``rgb_array``): the site, the cameras and their views, the robots,
        the parent's track and its covariance ellipse (x 100)."""
        if self.render_mode is None:
            return None
        episode = self._current("render()")
        assert episode.batch is not None
        from twin.envs.render import top_view_rgb

        track = episode.batch.track(episode.row)
        errors = episode.camera_errors_mm()
        return top_view_rgb(episode.scenario, episode.batch, track, errors, episode.row)
