"""Many episodes of :class:`twin.envs.CpsCampaignEnv` in one process, their noise executed
together: ``gymnasium.make_vec("camnet/CpsCampaign-v0", num_envs=N)`` (the registered
``vector_entry_point``).

Episodes that have played the same moves on the same site have executed the same plan
steps: they form a group, whose trials are the rows of one batch
(:class:`twin.batch.execute.BatchRun`), and a step of the plan runs once for all of them;
what the batch knows after it (:mod:`twin.envs.knowledge`) is computed once too, and the
group's observations are built in one call.
When the members of a group choose different moves, the largest part keeps the batch and
each other part replays the group's steps into a batch of its own (a trial gives the same
result alone or in any batch, so a split changes no number). Episodes that reset at the
same step on the same site start a group together.

Policies that repeat their moves (the paper's, a policy under evaluation) then cost one
batch per group; random moves split every group at the first decision, and run as fast as
separate environments.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import gymnasium
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from twin.batch.execute import BatchRun
from twin.batch.plan import Step
from twin.envs.campaign_env import CpsCampaignEnv
from twin.envs.knowledge import BatchKnowledge

__all__ = ["CpsCampaignVectorEnv"]


@dataclass
class _Group:
    """Episodes that have played the same moves on one site: rows of one batch.

    Attributes:
        batch: their trials. history: every plan step the batch executed, in order.
        known: what the batch knows (computed once per step for every member).
        members: each member's environment index and its row.
    """

    batch: BatchRun
    history: list[Step]
    known: BatchKnowledge
    members: dict[int, int] = field(default_factory=dict)


class CpsCampaignVectorEnv(VectorEnv):
    """``num_envs`` campaigns with their noise executed in shared batches (see the module).

    Args:
        num_envs: episodes run side by side.
        max_episode_steps: decisions before an episode is truncated (None: never).
        env_kwargs: the arguments of :class:`CpsCampaignEnv` (``scenario``,
            ``reward_mode``...), the same for every episode.
    """

    metadata = {  # noqa: RUF012  (Gymnasium's convention: a class attribute)
        "render_modes": ["rgb_array"],
        "render_fps": 2,
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self, num_envs: int = 1, max_episode_steps: int | None = None, **env_kwargs: Any
    ) -> None:
        if num_envs < 1:
            raise ValueError(f"num_envs must be >= 1, got {num_envs}")
        self.envs = [CpsCampaignEnv(**env_kwargs) for _ in range(num_envs)]
        self.num_envs = num_envs
        self.max_episode_steps = max_episode_steps
        self.render_mode = env_kwargs.get("render_mode")
        self.single_observation_space = self.envs[0].observation_space
        self.single_action_space = self.envs[0].action_space
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._groups: list[_Group] = []
        self._steps = np.zeros(num_envs, dtype=np.int64)
        self._autoreset = np.zeros(num_envs, dtype=bool)

    # -- resets --------------------------------------------------------------------------------
    def reset(
        self,
        *,
        seed: int | list[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[dict[str, NDArray[np.float64]], dict[str, Any]]:
        """Start every episode; ``seed`` an int (episode k gets ``seed + k``), a list, or
        None; ``options`` as :meth:`CpsCampaignEnv.reset`'s, for every episode."""
        if seed is None:
            seeds: list[int | None] = [None] * self.num_envs
        elif isinstance(seed, int):
            seeds = [seed + k for k in range(self.num_envs)]
        else:
            seeds = list(seed)
        if len(seeds) != self.num_envs:
            raise ValueError(f"{len(seeds)} seeds for {self.num_envs} environments")
        self._groups = []
        self._autoreset[:] = False
        self._start(list(range(self.num_envs)), seeds, options)
        infos: dict[str, Any] = {}
        for k, env in enumerate(self.envs):
            infos = self._add_info(infos, env._info(), k)
        return self._observations(), infos

    def _start(
        self, indices: list[int], seeds: list[int | None], options: dict[str, Any] | None
    ) -> None:
        """Reset the episodes ``indices``; those on one site start a group together."""
        starting: dict[int, list[tuple[int, int, tuple[Step, ...]]]] = {}
        for k, seed in zip(indices, seeds, strict=True):
            env = self.envs[k]
            self._leave(k)
            gymnasium.Env.reset(env, seed=seed)
            scenario, trial_seed = env._draw(options)
            steps = env._prepare(scenario, trial_seed)
            assert env.planner is not None
            starting.setdefault(id(env.planner.memo), []).append((k, trial_seed, steps))
            self._steps[k] = 0
        for episodes in starting.values():
            first = self.envs[episodes[0][0]]
            assert first.planner is not None
            steps = episodes[0][2]
            batch = BatchRun(first.planner.plan, [trial for _, trial, _ in episodes])
            for step in steps:
                batch.step(step)
            group = _Group(batch, list(steps), first.knowledge_of(batch))
            for row, (k, _, _) in enumerate(episodes):
                group.members[k] = row
                self.envs[k]._attach(batch, row, steps, group.known)
            self._groups.append(group)

    def _leave(self, k: int) -> None:
        """Episode ``k`` leaves its group (an empty group is dropped)."""
        for group in self._groups:
            group.members.pop(k, None)
        self._groups = [g for g in self._groups if g.members]

    # -- steps ---------------------------------------------------------------------------------
    def step(
        self, actions: NDArray[np.int64]
    ) -> tuple[
        dict[str, NDArray[np.float64]],
        NDArray[np.float64],
        NDArray[np.bool_],
        NDArray[np.bool_],
        dict[str, Any],
    ]:
        """Take each episode's move (an episode that ended at the last step is reset
        instead, its action ignored)."""
        actions = np.asarray(actions).reshape(self.num_envs)
        rewards = np.zeros(self.num_envs)
        terminated = np.zeros(self.num_envs, dtype=bool)
        truncated = np.zeros(self.num_envs, dtype=bool)
        infos: dict[str, Any] = {}
        resetting = np.flatnonzero(self._autoreset).tolist()
        # Every move is resolved before anything changes: with strict=True a forbidden move
        # raises and leaves the vector as it was.
        resolved = {
            k: self.envs[k]._resolve(int(actions[k]))
            for k in range(self.num_envs)
            if k not in resetting
        }
        if resetting:
            self._start(resetting, [None] * len(resetting), None)
        outcomes: dict[int, tuple[int, float, dict[str, Any] | None]] = {}
        for group in list(self._groups):
            # Members that take the same steps stay together (the same move gives the same
            # steps, unless the planner weighs it by the trial's own estimates).
            parts: dict[tuple[int, int], list[int]] = {}
            taken_steps: dict[tuple[int, int], tuple[int, tuple[Step, ...]]] = {}
            fallbacks: dict[int, dict[str, Any] | None] = {}
            for k in group.members:
                if k in resetting:
                    continue
                taken, fallbacks[k] = resolved[k]
                planner = self.envs[k].planner
                assert planner is not None
                steps = planner.act(taken)
                taken_steps[(taken, id(steps))] = (taken, steps)
                parts.setdefault((taken, id(steps)), []).append(k)
            if not parts:
                continue
            # The largest part keeps the batch; the others split off first, from the
            # group's steps so far.
            largest = max(parts, key=lambda a: len(parts[a]))
            order = [a for a in parts if a != largest] + [largest]
            for key in order:
                members = parts[key]
                taken, steps = taken_steps[key]
                target = group if key == largest else self._split(group, members)
                for step in steps:
                    target.batch.step(step)
                target.history.extend(steps)
                for k in members:
                    outcomes[k] = (taken, self.envs[k]._account(taken, steps), fallbacks[k])
        for k, env in enumerate(self.envs):
            if k in outcomes:
                taken, reward, fallback = outcomes[k]
                rewards[k], terminated[k], info = env._finish(taken, reward, fallback)
                self._steps[k] += 1
                truncated[k] = (
                    not terminated[k]
                    and self.max_episode_steps is not None
                    and self._steps[k] >= self.max_episode_steps
                )
            else:
                info = env._info()
            infos = self._add_info(infos, info, k)
        self._autoreset = terminated | truncated
        return self._observations(), rewards, terminated, truncated, infos

    def _split(self, group: _Group, members: list[int]) -> _Group:
        """Move ``members`` out of ``group`` into a batch of their own that has executed
        the group's steps."""
        first = self.envs[members[0]]
        assert first.planner is not None
        seeds = [self.envs[k].trial_seed for k in members]
        batch = BatchRun(first.planner.plan, seeds)
        for step in group.history:
            batch.step(step)
        part = _Group(batch, list(group.history), first.knowledge_of(batch))
        for row, k in enumerate(members):
            group.members.pop(k)
            part.members[k] = row
            self.envs[k]._join(batch, row, part.known)
        self._groups.append(part)
        return part

    # -- what comes back -----------------------------------------------------------------------
    def _observations(self) -> dict[str, NDArray[np.float64]]:
        """Every episode's observation, each group's built at once (its members share their
        campaign's state; their rows of the batch differ)."""
        out: dict[str, NDArray[np.float64]] = {}
        for group in self._groups:
            indices = list(group.members)
            part = self.envs[indices[0]].observations([group.members[k] for k in indices])
            for key, values in part.items():
                if key not in out:
                    out[key] = np.zeros((self.num_envs, *values.shape[1:]))
                out[key][indices] = values
        return out

    def action_masks(self) -> NDArray[np.bool_]:
        """(num_envs, n) the moves each episode allows now."""
        return np.stack([env.action_masks() for env in self.envs])

    def render(self) -> tuple[NDArray[np.uint8] | None, ...] | None:
        """Each episode's top view (``rgb_array``), or None."""
        if self.render_mode is None:
            return None
        return tuple(env.render() for env in self.envs)

    def close_extras(self, **kwargs: Any) -> None:
        for env in self.envs:
            env.close()
