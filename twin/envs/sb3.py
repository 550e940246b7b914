"""Stable-Baselines3's ``VecEnv`` over the environment's own vector
(:class:`twin.envs.vector.CpsCampaignVectorEnv`), for MaskablePPO and the other
algorithms of Stable-Baselines3 and sb3-contrib.

Stable-Baselines3 expects of a ``VecEnv`` what the vector does otherwise: an episode that
ends is reset in the same step (the observation returned is the next episode's first,
``infos[i]["terminal_observation"]`` the last one of the episode that ended,
``infos[i]["TimeLimit.truncated"]`` whether the step limit cut it), infos a list of dicts,
and the masks from ``env_method("action_masks")`` (as ``MaskablePPO`` reads them: never all
False, since no episode stands after its last step). :class:`CampaignVecAdapter` is that
logic without Stable-Baselines3 (whose ``VecEnv`` imports torch); :func:`make_sb3_vec_env`
makes the ``VecEnv`` itself, a subclass of both, where Stable-Baselines3 is installed::

    from sb3_contrib import MaskablePPO
    from twin.envs.sb3 import make_sb3_vec_env

    venv = make_sb3_vec_env(16, scenario="paper_hall", planner="stands")
    model = MaskablePPO("MultiInputPolicy", venv).learn(10_000)
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.envs import MAX_EPISODE_STEPS
from twin.envs.vector import CpsCampaignVectorEnv

__all__ = ["CampaignVecAdapter", "make_sb3_vec_env"]

Indices = None | int | Iterable[int]
"""Stable-Baselines3's ``VecEnvIndices``: every episode, one, or some."""


class CampaignVecAdapter:
    """The methods of Stable-Baselines3's ``VecEnv`` over the environment's vector (see the
    module), without importing Stable-Baselines3 or torch.

    Args:
        num_envs: episodes run side by side.
        max_episode_steps: decisions before an episode is truncated (None: never).
        env_kwargs: the arguments of :class:`twin.envs.CpsCampaignEnv` (``scenario``,
            ``planner``...).

    Attributes:
        venv: the vector. observation_space, action_space: one episode's (as
            Stable-Baselines3 has them). reset_infos: each episode's info at its last reset.
    """

    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = MAX_EPISODE_STEPS,
        **env_kwargs: Any,
    ) -> None:
        self.venv = CpsCampaignVectorEnv(num_envs, max_episode_steps, **env_kwargs)
        self.num_envs = num_envs
        self.observation_space = self.venv.single_observation_space
        self.action_space = self.venv.single_action_space
        self.render_mode = self.venv.render_mode
        self.metadata = {"render_modes": ["rgb_array"] if self.render_mode else []}
        self.reset_infos: list[dict[str, Any]] = [{} for _ in range(num_envs)]
        self._seeds: list[int | None] = [None] * num_envs
        self._options: list[dict[str, Any]] = [{} for _ in range(num_envs)]
        self._actions: NDArray[np.int64] | None = None

    # -- seeds and options for the next reset (Stable-Baselines3's conventions) ----------------
    def seed(self, seed: int | None = None) -> list[int | None]:
        """Episode k's next reset is seeded ``seed + k`` (a random seed for None)."""
        if seed is None:
            seed = int(np.random.default_rng().integers(np.iinfo(np.uint32).max))
        self._seeds = [seed + k for k in range(self.num_envs)]
        return list(self._seeds)

    def set_options(self, options: list[dict[str, Any]] | dict[str, Any] | None = None) -> None:
        """The options of the next reset (:meth:`twin.envs.CpsCampaignEnv.reset`'s), the same
        for every episode."""
        if options is None:
            options = {}
        self._options = (
            [dict(options) for _ in range(self.num_envs)]
            if isinstance(options, dict)
            else [dict(o) for o in options]
        )

    # -- episodes ------------------------------------------------------------------------------
    def reset(self) -> dict[str, NDArray[np.float32]]:
        """Start every episode (with the seeds and options set, used once); the
        observations.

        Raises:
            ValueError: the episodes' options differ (the vector takes one for all), or
                the environment refuses them.
        """
        options = self._options[0]
        if any(o != options for o in self._options):
            raise ValueError("reset options must be the same for every episode of the vector")
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        obs, infos = self.venv.reset(seed=seeds, options=options or None)
        self.reset_infos = self._split(infos)
        self._seeds = [None] * self.num_envs
        self._options = [{} for _ in range(self.num_envs)]
        return obs

    def reset_episodes(self, indices: Indices) -> dict[str, NDArray[np.float32]]:
        """Start new episodes for ``indices`` now (the others go on); every episode's
        observation (see :meth:`CpsCampaignVectorEnv.reset_episodes`)."""
        chosen = self._indices(indices)
        obs, infos = self.venv.reset_episodes(chosen)
        split = self._split(infos)
        for k in chosen:
            self.reset_infos[k] = split[k]
        return obs

    def step_async(self, actions: NDArray[np.int64]) -> None:
        """Each episode's move (an int each, ``num_envs`` of them), taken at
        :meth:`step_wait`."""
        self._actions = np.asarray(actions).reshape(self.num_envs)

    def step_wait(
        self,
    ) -> tuple[
        dict[str, NDArray[np.float32]], NDArray[np.float32], NDArray[np.bool_], list[dict[str, Any]]
    ]:
        """Take the moves; (observations, rewards, dones, infos), an episode that ended reset
        in the same step (see the module).

        Raises:
            RuntimeError: no moves were given (:meth:`step_async`).
        """
        if self._actions is None:
            raise RuntimeError("call step_async(actions) before step_wait()")
        actions, self._actions = self._actions, None
        obs, rewards, terminated, truncated, infos = self.venv.step(actions)
        dones = terminated | truncated
        split = self._split(infos)
        ended = np.flatnonzero(dones).tolist()
        for k in ended:
            split[k]["terminal_observation"] = {key: v[k].copy() for key, v in obs.items()}
            split[k]["TimeLimit.truncated"] = bool(truncated[k] and not terminated[k])
        if ended:
            obs = self.reset_episodes(ended)
        return obs, rewards.astype(np.float32), dones, split

    def step(
        self, actions: NDArray[np.int64]
    ) -> tuple[
        dict[str, NDArray[np.float32]], NDArray[np.float32], NDArray[np.bool_], list[dict[str, Any]]
    ]:
        """:meth:`step_async` then :meth:`step_wait`."""
        self.step_async(actions)
        return self.step_wait()

    def action_masks(self) -> NDArray[np.bool_]:
        """(num_envs, n) the moves each episode allows now."""
        return self.venv.action_masks()

    # -- the episodes' environments ------------------------------------------------------------
    def get_attr(self, attr_name: str, indices: Indices = None) -> list[Any]:
        """``attr_name`` of each episode's environment (:class:`twin.envs.CpsCampaignEnv`)."""
        return [getattr(self.venv.envs[k], attr_name) for k in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: Indices = None) -> None:
        """Set ``attr_name`` of each episode's environment."""
        for k in self._indices(indices):
            setattr(self.venv.envs[k], attr_name, value)

    def env_method(
        self, method_name: str, *method_args: Any, indices: Indices = None, **method_kwargs: Any
    ) -> list[Any]:
        """Call ``method_name`` of each episode's environment (``"action_masks"``: each
        one's (n,) mask, as MaskablePPO reads them)."""
        return [
            getattr(self.venv.envs[k], method_name)(*method_args, **method_kwargs)
            for k in self._indices(indices)
        ]

    def env_is_wrapped(self, wrapper_class: type, indices: Indices = None) -> list[bool]:
        """Whether each episode's environment is wrapped by ``wrapper_class``: never."""
        return [False for _ in self._indices(indices)]

    def get_images(self) -> list[NDArray[np.uint8] | None]:
        """Each episode's top view (``render_mode="rgb_array"``)."""
        return [env.render() for env in self.venv.envs]

    def close(self) -> None:
        self.venv.close()

    # -- helpers -------------------------------------------------------------------------------
    def _indices(self, indices: Indices) -> list[int]:
        """The episodes ``indices`` names (Stable-Baselines3's ``_get_indices``).

        Raises:
            ValueError: an index outside ``0 .. num_envs - 1``.
        """
        if indices is None:
            chosen = list(range(self.num_envs))
        elif isinstance(indices, (int, np.integer)):
            chosen = [int(indices)]
        else:
            chosen = [int(k) for k in indices]
        for k in chosen:
            if not 0 <= k < self.num_envs:
                raise ValueError(f"episode {k}: expected an index in 0 .. {self.num_envs - 1}")
        return chosen

    def _split(self, infos: dict[str, Any]) -> list[dict[str, Any]]:
        """Gymnasium's dict of per-episode arrays (nested for a dict) as one dict an
        episode."""
        return [_one(infos, k) for k in range(self.num_envs)]


def _one(infos: dict[str, Any], k: int) -> dict[str, Any]:
    """Episode ``k``'s info from a vector's (a key that ``_key`` marks absent left out)."""
    out: dict[str, Any] = {}
    for key, values in infos.items():
        if key.startswith("_"):
            continue
        present = infos.get(f"_{key}")
        if present is not None and not present[k]:
            continue
        out[key] = _one(values, k) if isinstance(values, dict) else values[k]
    return out


def make_sb3_vec_env(
    num_envs: int = 1, max_episode_steps: int | None = MAX_EPISODE_STEPS, **env_kwargs: Any
) -> Any:
    """A Stable-Baselines3 ``VecEnv`` (a subclass of its ``VecEnv`` and
    :class:`CampaignVecAdapter`) of ``num_envs`` episodes.

    Raises:
        ImportError: Stable-Baselines3 is not installed.
    """
    from stable_baselines3.common.vec_env import VecEnv  # imports torch

    class CpsCampaignVecEnv(CampaignVecAdapter, VecEnv):  # type: ignore[misc]
        """The environment's vector as Stable-Baselines3's ``VecEnv``."""

        def __init__(self) -> None:
            CampaignVecAdapter.__init__(self, num_envs, max_episode_steps, **env_kwargs)
            VecEnv.__init__(self, num_envs, self.observation_space, self.action_space)

    return CpsCampaignVecEnv()
