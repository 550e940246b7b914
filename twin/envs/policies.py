"""Baseline policies for :class:`twin.envs.CpsCampaignEnv`, by the names ``twin strategies``
knows them by.

A policy is called once per episode to make an actor (``policy(env, seed)``), and the actor
once per step with the observation and the info (``actor(obs, info) -> action``). The
actors read the environment's moves and what its campaign knows (never the truth), and take
only allowed moves.

- ``paper``: what ``twin run --strategy paper`` does: the scenario's visits in order, the
  children in line ahead (the scenario's formation), legs of the scenario's step;
- ``side_by_side``: the same visits and steps with the children side by side;
- ``greedy``: between travels, the move that lowers the predicted mean camera error most
  per metre of travel (calibrating where it stands costs none; a station it calibrated
  from once is not used again: its data would be the same); on a leg, the in-line
  formation and the longest step whose formation has room;
- ``random``: a move drawn uniformly from those allowed.

A saved MaskablePPO model (a ``.zip`` of sb3-contrib) is a policy too
(:func:`policy_for`): its deterministic action under the mask, from the observation alone.
Loading one needs sb3-contrib (the ``rl`` extra), imported only then.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.envs.campaign_env import CpsCampaignEnv
from twin.envs.site_stations import visit_stations

Actor = Callable[[dict[str, NDArray[np.float32]], dict[str, Any]], int]
"""Chooses a move from an observation and an info."""

Policy = Callable[[CpsCampaignEnv, int], Actor]
"""Makes an actor for one episode of an environment, from a seed."""

CALIBRATION_ERROR_MM = 5.0
"""What the greedy policy expects a calibration to add to the parent's transfer error before
it has calibrated a camera, mm (the hall's local 3D error is a few mm)."""

MIN_GAIN_MM = 0.5
"""The greedy policy ends when no move lowers the mean predicted error by this much, mm."""


def _allowed(info: dict[str, Any], action: int) -> bool:
    return bool(info["action_mask"][action])


def _leg(env: CpsCampaignEnv, info: dict[str, Any], formation: str, factor: float) -> int:
    """The leg in ``formation`` with the step nearest ``factor``, or its fallback."""
    layout = env.layout
    action = layout.leg(formation, factor)
    return action if _allowed(info, action) else layout.fallback(action, info["action_mask"])


def _in_order(env: CpsCampaignEnv, formation: str) -> Actor:
    """The scenario's visits in order, legs of the scenario's step in ``formation``."""
    planner = env.planner
    assert env.scenario is not None
    assert planner is not None
    order = visit_stations(env.scenario, planner.stations)
    state = {"next": 0}
    layout = env.layout

    def act(obs: dict[str, NDArray[np.float32]], info: dict[str, Any]) -> int:
        if info["decision"] == "leg":
            return _leg(env, info, formation, 1.0)
        assert env.planner is not None
        while state["next"] < len(order):
            station = order[state["next"]]
            if env.planner.here() == station:
                state["next"] += 1
                return layout.calibrate
            action = layout.go_to(env.planner.order.index(station))
            if _allowed(info, action):
                return action
            state["next"] += 1  # out of reach: the next visit
        return layout.end

    return act


def paper(env: CpsCampaignEnv, seed: int) -> Actor:
    """The paper's strategy as moves (see the module)."""
    return _in_order(env, "in_line")


def side_by_side(env: CpsCampaignEnv, seed: int) -> Actor:
    """The paper's visits with the children side by side."""
    return _in_order(env, "side_by_side")


def greedy(env: CpsCampaignEnv, seed: int) -> Actor:
    """The move that lowers the predicted camera error most per metre (see the module)."""
    layout = env.layout
    longest = max(layout.step_factors)
    tried: set[str] = set()  # stations calibrated from: their campaign would be the same

    def act(obs: dict[str, NDArray[np.float32]], info: dict[str, Any]) -> int:
        if info["decision"] == "leg":
            return _leg(env, info, "in_line", longest)
        planner = env.planner
        assert planner is not None
        states = env.camera_states()
        n = len(states)

        def gain(k: int) -> float:
            """The mean predicted error's decrease if camera k were calibrated from the
            parent's pose as it is now, mm."""
            s = states[k]
            own = 1e3 * s.calibration_error if s.calibrated else CALIBRATION_ERROR_MM
            after = float(np.hypot(1e3 * s.transfer_now, own))
            before = 1e3 * s.predicted_error if s.calibrated else env.uncalibrated_error_mm
            return (before - after) / n

        here, camera_here = planner.here(), planner.here_camera()
        names = [c.name for c in env.scenario.cameras] if env.scenario else []
        if (
            camera_here is not None
            and here not in tried
            and gain(names.index(camera_here)) >= MIN_GAIN_MM
        ):
            tried.add(here)
            return layout.calibrate
        best, best_rate = layout.end, 0.0
        for j, name in enumerate(planner.order):
            camera = planner.stations[name].camera
            g = gain(names.index(camera))
            action = layout.go_to(j)
            if g < MIN_GAIN_MM or name in tried or not _allowed(info, action):
                continue
            rate = g / max(planner.route_distance(planner.stations[name]), 1.0)
            if rate > best_rate:
                best, best_rate = action, rate
        return best

    return act


def random(env: CpsCampaignEnv, seed: int) -> Actor:
    """A move drawn uniformly from the allowed ones, from its own generator."""
    rng = np.random.default_rng(seed)

    def act(obs: dict[str, NDArray[np.float32]], info: dict[str, Any]) -> int:
        return int(rng.choice(np.flatnonzero(info["action_mask"])))

    return act


POLICIES: dict[str, Policy] = {
    "paper": paper,
    "side_by_side": side_by_side,
    "greedy": greedy,
    "random": random,
}
"""Each policy by name (:data:`twin.envs.POLICY_NAMES`, in that order)."""


def policy_named(name: str) -> Policy:
    """The policy called ``name``.

    Raises:
        ValueError: no policy has that name (the message lists those that do).
    """
    try:
        return POLICIES[name]
    except KeyError:
        raise ValueError(f"unknown policy {name!r}; policies: {', '.join(POLICIES)}") from None


MODEL_SUFFIX = ".zip"
"""A policy given by a path with this suffix is a saved MaskablePPO model."""


def is_model(spec: str) -> bool:
    """Whether ``spec`` names a saved model (a path ending in :data:`MODEL_SUFFIX`) rather
    than a policy of :data:`POLICIES`."""
    return spec not in POLICIES and spec.lower().endswith(MODEL_SUFFIX)


def policy_for(spec: str) -> Policy:
    """The policy ``spec`` names: one of :data:`POLICIES`, or a saved MaskablePPO model
    (a path ending in ``.zip``, loaded now, on the CPU).

    Raises:
        ValueError: an unknown name, a model file that is missing or is not a saved
            MaskablePPO, or sb3-contrib is not installed (the message names ``spec``).
    """
    if not is_model(spec):
        return policy_named(spec)
    path = Path(spec)
    if not path.is_file():
        raise ValueError(f"policy {spec}: no such file; expected a saved MaskablePPO model (.zip)")
    try:
        from sb3_contrib import MaskablePPO  # imports torch
    except ImportError:
        raise ValueError(
            f"policy {spec}: loading a saved model needs sb3-contrib, which is not installed "
            "(pip install 'camnet-twin[rl]', or make test-rl's .venv-rl)"
        ) from None
    try:
        model = MaskablePPO.load(path, device="cpu")
    except Exception as exc:  # a zip of something else: whatever the loader raises
        raise ValueError(f"policy {spec}: not a saved MaskablePPO model ({exc})") from None
    return model_policy(model, spec)


def model_policy(model: Any, name: str = "model") -> Policy:
    """A policy of a trained MaskablePPO ``model``: at each step its deterministic action
    under the episode's mask.

    Raises (when an episode starts):
        ValueError: the model's observation or action space is not the environment's
            (it was trained with other ``max_cameras``, ``max_stations`` or moves).
    """

    def make(env: CpsCampaignEnv, seed: int) -> Actor:
        if model.observation_space != env.observation_space or (
            model.action_space != env.action_space
        ):
            raise ValueError(
                f"policy {name}: the model's observation or action space is not the "
                f"environment's ({model.action_space} against {env.action_space}): it was "
                "trained with other max_cameras, max_stations or moves"
            )

        def act(obs: dict[str, NDArray[np.float32]], info: dict[str, Any]) -> int:
            action, _ = model.predict(obs, action_masks=info["action_mask"], deterministic=True)
            return int(action)

        return act

    return make
