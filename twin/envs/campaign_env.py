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
(reported in ``info["fallback"]``); with ``strict=True`` it raises ``ValueError``.

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
from dataclasses import replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from numpy.typing import NDArray

from twin.batch.execute import BatchRun, VisitOutcome, transfer_rms
from twin.batch.plan import BatchPlan, Calibrate, Step
from twin.envs.free_space import FreeSpace
from twin.envs.moves import MoveLayout
from twin.envs.observation import (
    CameraState,
    StationState,
    build_observation,
    observation_space,
)
from twin.envs.planner import CampaignPlanner
from twin.envs.sites import random_site
from twin.scenario import load_scenario
from twin.scenario.schema import Scenario

__all__ = ["REWARD_MODES", "CpsCampaignEnv"]

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
    }
)
"""What pickling leaves out and rebuilds by replaying the episode's moves."""

RANDOM = "random"
"""``scenario`` for a random site at each reset."""


def _scenario(spec: str | Path | Scenario | None) -> Scenario | None:
    """A scenario from a path or a scenario; None for random sites."""
    if spec is None or (isinstance(spec, str) and spec == RANDOM):
        return None
    if isinstance(spec, Scenario):
        return spec
    return load_scenario(spec)


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
    ) -> None:
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
        self.planner: CampaignPlanner | None = None
        self.batch: BatchRun | None = None
        self.scenario: Scenario | None = None
        self._free: FreeSpace | None = None
        self._free_for: Scenario | None = None
        self._episode: dict[str, Any] = {}
        self._steps: list[Step] = []
        self._fallbacks = 0
        self._row = 0  # the episode's trial in self.batch

    # -- episodes ---------------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, NDArray[np.float64]], dict[str, Any]]:
        """Start a campaign. ``options["scenario"]``: a scenario file, a
        :class:`Scenario` or ``"random"`` for this episode (default: the environment's)."""
        super().reset(seed=seed)
        scenario, trial_seed = self._draw(options)
        self._start_episode(scenario, trial_seed)
        return self._observation(), self._info()

    # The episode's parts, which a vector of environments (twin.envs.vector) runs for many
    # episodes at once: draw the site and the noise seed, prepare the campaign, attach the
    # trials that execute it; then per move resolve it, take it, execute it, account for it.
    def _draw(self, options: dict[str, Any] | None) -> tuple[Scenario, int]:
        """The episode's site and noise seed, from the generator (after seeding it)."""
        options = options or {}
        scenario = (
            _scenario(options["scenario"]) if "scenario" in options else self.default_scenario
        )
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
        planner = CampaignPlanner(scenario, self.layout, budget)  # may refuse the site
        self._close_episode()
        self.planner = planner
        self.scenario = scenario
        if self._free_for is not scenario:
            self._free, self._free_for = FreeSpace(scenario.space), scenario
        self._episode = {"scenario": scenario, "trial_seed": trial_seed, "moves": []}
        return self.planner.take_pending()

    def _attach(self, batch: BatchRun, row: int, steps: tuple[Step, ...]) -> None:
        """The episode's trial is row ``row`` of ``batch``, which has executed ``steps``."""
        assert self.planner is not None
        self.batch, self._row = batch, row
        self._steps = list(steps)
        self._time = self.planner.time
        self._distance = 0.0
        self._predicted = self._mean_predicted_mm()
        self._fallbacks = 0

    def step(
        self, action: int
    ) -> tuple[dict[str, NDArray[np.float64]], float, bool, bool, dict[str, Any]]:
        """Take a move (see :mod:`twin.envs.moves`)."""
        action, fallback = self._resolve(action)
        reward = self._apply(action)
        return self._outcome(action, reward, fallback)

    def _resolve(self, action: int) -> tuple[int, dict[str, Any] | None]:
        """The move to take for ``action`` (its fallback if it is forbidden), and the
        fallback's report (None when the move is allowed)."""
        planner = self.planner
        if planner is None:
            raise RuntimeError("call reset() before step()")
        if planner.done:
            raise RuntimeError("the campaign is over: call reset()")
        action = int(action)
        valid = 0 <= action < self.layout.size
        if valid and planner.mask[action]:
            return action, None
        what = self.layout.describe(action) if valid else f"action {action}"
        if self.strict:
            raise ValueError(f"{what} is not allowed now (see action_masks())")
        taken = self.layout.fallback(action if valid else -1, planner.mask)
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
        assert self.planner is not None
        info = self._info()
        info["move"] = self.layout.describe(action)
        if fallback is not None:
            info["fallback"] = fallback
        return self._observation(), reward, self.planner.done, False, info

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
        self.planner, self.batch = None, None

    # -- what the campaign knows -------------------------------------------------------------------
    def _parent_estimate(self) -> tuple[NDArray[np.float64], float, NDArray[np.float64]]:
        """The trial's parent estimate: (3,) instrument centre m, yaw rad, (4, 4) covariance."""
        assert self.batch is not None
        parent = self.batch.cps.parent
        return (
            parent.translation[self._row],
            float(parent.yaw[self._row]),
            parent.covariance[self._row],
        )

    def _delivered(self) -> dict[str, VisitOutcome]:
        """Each camera's calibration the campaign delivers: of its visits that calibrated
        it, the one with the lowest predicted world-frame error."""
        assert self.batch is not None
        best: dict[str, tuple[float, VisitOutcome]] = {}
        for (camera, _), outcome in self.batch.visits.items():
            if not bool(outcome.calibrated[self._row]):
                continue
            predicted = math.hypot(
                outcome.predicted_transfer[self._row], outcome.predicted_calibration[self._row]
            )
            if camera not in best or predicted < best[camera][0]:
                best[camera] = (predicted, outcome)
        return {camera: outcome for camera, (_, outcome) in best.items()}

    def camera_states(self) -> list[CameraState]:
        """What the campaign knows of each camera, in the site's order."""
        assert self.batch is not None
        assert self.planner is not None
        assert self.scenario is not None
        delivered = self._delivered()
        parent = self.batch.cps.parent
        here = self.planner.here_camera()
        out = []
        for cam in self.scenario.cameras:
            position = np.asarray(cam.position, dtype=float)
            outcome = delivered.get(cam.name)
            transfer = 0.0 if outcome is None else float(outcome.predicted_transfer[self._row])
            own = 0.0 if outcome is None else float(outcome.predicted_calibration[self._row])
            out.append(
                CameraState(
                    outcome is not None,
                    math.hypot(transfer, own),
                    own,
                    float(transfer_rms(parent, position[None])[self._row]),
                    position,
                    here == cam.name,
                )
            )
        return out

    def station_states(self) -> list[StationState]:
        """What the campaign knows of each calibration station, in the order of
        ``go_to``."""
        assert self.planner is not None
        assert self.scenario is not None
        planner = self.planner
        names = [c.name for c in self.scenario.cameras]
        calibrated = self._delivered()
        here = planner.here()
        out = []
        for name in planner.order:
            station = planner.stations[name]
            assert station.camera is not None
            out.append(
                StationState(
                    names.index(station.camera),
                    station.xy,
                    planner.route_distance(station),
                    station.camera in calibrated,
                    here == name,
                )
            )
        return out

    def _mean_predicted_mm(self) -> float:
        states = self.camera_states()
        errors = [
            1e3 * s.predicted_error if s.calibrated else self.uncalibrated_error_mm for s in states
        ]
        return float(np.mean(errors)) if errors else 0.0

    def camera_errors_mm(self) -> dict[str, float]:
        """The true world-frame position error of each camera calibrated so far (the
        calibration delivered: of its visits, the one with the lowest predicted error), mm."""
        return {
            camera: 1e3 * float(outcome.position_error[self._row])
            for camera, outcome in self._delivered().items()
        }

    def _mean_true_mm(self) -> float:
        assert self.scenario is not None
        errors = self.camera_errors_mm()
        return float(
            np.mean([errors.get(c.name, self.uncalibrated_error_mm) for c in self.scenario.cameras])
        )

    def parent_error_mm(self) -> float:
        """The trial's parent position error at its last fix, mm."""
        assert self.batch is not None
        estimate, truth = self.batch.fixes[-1]
        return 1e3 * float(np.linalg.norm(estimate.translation[self._row] - truth[self._row]))

    def _child_estimate(self, child: str) -> NDArray[np.float64]:
        """(3,) a child's estimate: its CPS position (its own before CPS measured it), m,
        and its own yaw, rad."""
        assert self.batch is not None
        believed = self.batch.robots[child].believed[self._row]
        try:
            xy = self.batch.cps.child_position(child)[self._row, :2]
        except ValueError:  # not measured yet
            xy = believed[:2]
        return np.array([xy[0], xy[1], believed[2]])

    def _observation(self) -> dict[str, NDArray[np.float64]]:
        planner, batch = self.planner, self.batch
        assert planner is not None
        assert batch is not None
        assert self._free is not None
        centre, yaw, covariance = self._parent_estimate()
        children = np.array([self._child_estimate(c) for c in batch.plan.children])
        goal = planner.goal_station
        left = planner.budget_m - float(batch.distance[self._row])
        return build_observation(
            decision=planner.decision,
            parent_xy=centre[:2],
            parent_yaw=yaw,
            parent_covariance=covariance,
            children_pose=children,
            travel=(float(batch.distance[self._row]), left, planner.time),
            goal_xy=None if goal is None or planner.decision != "leg" else goal.xy,
            cameras=self.camera_states(),
            max_cameras=self.max_cameras,
            stations=self.station_states(),
            max_stations=self.layout.max_stations,
            free_space=self._free.rays(centre[:2], yaw),
        )

    def _info(self) -> dict[str, Any]:
        assert self.planner is not None
        assert self.batch is not None
        return {
            "camera_errors_mm": self.camera_errors_mm(),
            "parent_error_mm": self.parent_error_mm(),
            "distance_m": float(self.batch.distance[self._row]),
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

        track = [estimate.translation[self._row] for estimate, _ in self.batch.fixes]
        return top_view_rgb(self.scenario, self.batch, track, self.camera_errors_mm(), self._row)
