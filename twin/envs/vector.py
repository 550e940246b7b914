"""Many episodes of :class:`twin.envs.CpsCampaignEnv` in one process, their noise executed
together: ``gymnasium.make_vec("camnet/CpsCampaign-v0", num_envs=N)`` (the registered
``vector_entry_point``).

The episodes on one site are the rows of one batch (:class:`twin.batch.execute.BatchRun`),
each its own campaign: at every step each episode's move gives its plan steps, and
:func:`twin.batch.rows.execute_rows` runs them all, rows that take the same kind of step at
once (the legs' drives, placements and fixes in lock step; data sets for the rows that take
the same ones). What the batch knows after a step (:mod:`twin.envs.knowledge`) is computed
once for every row, and the observations of episodes whose campaigns stand at the same
decision are built in one call.

Starting an episode runs the site's reference data (a hundred steps or so), which would
cost more than the moves of random play. So each episode has spare rows, which start its
next :data:`SPARES` episodes ahead (their noise seeds are known: they come from the
episode's own generator), together with the episodes that have to start at once: an
episode that ends takes its next spare, and most resets cost nothing.

A trial gives the same result alone or in any batch, so every episode is the single
environment's, bit for bit. Policies that repeat their moves share their steps' runs;
random moves on the site's table (``planner="stands"``) share the legs' rounds and the
knowledge.
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
from twin.batch.rows import execute_rows
from twin.batch.steps import Step
from twin.envs.campaign_env import CpsCampaignEnv, check_options
from twin.envs.episode import Episode, SiteShare
from twin.envs.knowledge import BatchKnowledge

__all__ = ["SPARES", "CpsCampaignVectorEnv"]

SPARES = 3
"""Episodes each episode of a vector starts ahead (see the module)."""


@dataclass
class _Pool:
    """The episodes on one site: rows of one batch (:data:`SPARES` + 1 an episode: the one
    it plays and its spares).

    Attributes:
        site: the planners' shared table or memo of the site (kept: it names the pool).
        batch: the trials. known: what they know (computed once per step for every row).
        members: the episodes on the site now.
    """

    site: SiteShare
    batch: BatchRun
    known: BatchKnowledge
    members: set[int] = field(default_factory=set)


@dataclass
class _Starts:
    """The episodes of a pool that start at a step.

    Attributes:
        pool: their pool. rows: the rows restarted, with their seeds (those that take a
            spare are not). episodes: each episode's start steps.
    """

    pool: _Pool
    rows: dict[int, int] = field(default_factory=dict)
    episodes: dict[int, tuple[Step, ...]] = field(default_factory=dict)


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
        self._pools: dict[int, _Pool] = {}  # by the id of the site's table or memo
        # Episode k's rows in its site's batch (k, k + N, k + 2N...): the one it plays, and
        # its spares, started ahead for its next episodes (row, seed), in order, with other
        # episodes that start (to share their steps).
        self._active = np.arange(num_envs)
        self._spares: list[list[tuple[int, int]]] = [[] for _ in range(num_envs)]
        self._home: dict[int, _Pool] = {}
        self._steps = np.zeros(num_envs, dtype=np.int64)
        self._autoreset = np.zeros(num_envs, dtype=bool)

    # -- resets --------------------------------------------------------------------------------
    def reset(
        self,
        *,
        seed: int | list[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[dict[str, NDArray[np.float32]], dict[str, Any]]:
        """Start every episode; ``seed`` an int (episode k gets ``seed + k``), a list, or
        None; ``options`` as :meth:`CpsCampaignEnv.reset`'s, for every episode.

        Raises:
            ValueError: bad seeds, or options as :meth:`CpsCampaignEnv.reset` refuses them
                (nothing is reset).
        """
        if options is not None:
            options = check_options(options, self.envs[0].default_scenario)
        if seed is None:
            seeds: list[int | None] = [None] * self.num_envs
        elif isinstance(seed, int):
            seeds = [seed + k for k in range(self.num_envs)]
        else:
            seeds = list(seed)
        if len(seeds) != self.num_envs:
            raise ValueError(f"{len(seeds)} seeds for {self.num_envs} environments")
        self._pools, self._home = {}, {}
        self._autoreset[:] = False
        self._run(self._start(list(range(self.num_envs)), seeds, options))
        infos: dict[str, Any] = {}
        for k in range(self.num_envs):
            infos = self._add_info(infos, self._episode(k).info(), k)
        return self._observations(), infos

    def reset_episodes(
        self,
        indices: list[int],
        seeds: list[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[dict[str, NDArray[np.float32]], dict[str, Any]]:
        """Start new episodes for ``indices`` now (the others go on with theirs): each as
        :meth:`CpsCampaignEnv.reset` with its seed (None: the next of its generator) and
        ``options``. Every episode's observation and info come back; an episode that ended
        at the last step and is reset here is not reset again at the next step (a reset in
        the same step, as Stable-Baselines3 expects).

        Raises:
            ValueError: an index outside ``0 .. num_envs - 1`` or repeated, seeds that are
                not one an index, or options :meth:`CpsCampaignEnv.reset` refuses
                (nothing is reset).
        """
        indices = [int(k) for k in indices]
        if any(not 0 <= k < self.num_envs for k in indices) or len(set(indices)) < len(indices):
            raise ValueError(
                f"episodes {indices}: expected distinct indices in 0 .. {self.num_envs - 1}"
            )
        if seeds is None:
            seeds = [None] * len(indices)
        if len(seeds) != len(indices):
            raise ValueError(f"{len(seeds)} seeds for {len(indices)} episodes")
        if options is not None:
            options = check_options(options, self.envs[0].default_scenario)
        if indices:
            self._run(self._start(indices, list(seeds), options))
            self._autoreset[indices] = False
        infos: dict[str, Any] = {}
        for k in range(self.num_envs):
            infos = self._add_info(infos, self._episode(k).info(), k)
        return self._observations(), infos

    def _start(
        self, indices: list[int], seeds: list[int | None], options: dict[str, Any] | None
    ) -> dict[int, _Starts]:
        """Reset the episodes ``indices``: each takes its next spare row where that has
        started its episode already, or starts its row of its site's batch again (then the
        spares of the site's episodes start their next episodes with it). Returns, by pool,
        the rows restarted, whose start steps are yet to run (:meth:`_run`)."""
        if options is not None or any(seed is not None for seed in seeds):
            self._spares = [[] for _ in range(self.num_envs)]  # the generators start again
        starts: dict[int, _Starts] = {}
        for k, seed in zip(indices, seeds, strict=True):
            env = self.envs[k]
            self._leave(k)
            gymnasium.Env.reset(env, seed=seed)
            episode = env.prepare(*env.draw(options))
            pool = self._pool_of(episode)
            if self._home.get(k) is not pool:
                self._spares[k] = []  # its spares were started on another site
            self._home[k] = pool
            pool.members.add(k)
            self._steps[k] = 0
            part = starts.setdefault(id(pool), _Starts(pool))
            if self._spares[k] and self._spares[k][0][1] == episode.trial_seed:
                self._active[k] = self._spares[k].pop(0)[0]
            else:
                self._spares[k] = []
                part.rows[self._active[k]] = episode.trial_seed
            part.episodes[k] = episode.start_steps
        self._pools = {key: p for key, p in self._pools.items() if p.members}
        for part in starts.values():
            if not part.rows:
                continue
            for j in sorted(part.pool.members):
                queued = self._spares[j]
                if len(queued) == SPARES:
                    continue
                seeds = self._next_seeds(j)
                used = {int(self._active[j])} | {row for row, _ in queued}
                free = [j + m * self.num_envs for m in range(SPARES + 1)]
                free = [row for row in free if row not in used]
                for seed in seeds[len(queued) :]:
                    row = free.pop(0)
                    queued.append((row, seed))
                    part.rows[row] = seed
            part.pool.batch.restart(list(part.rows), list(part.rows.values()))
        return starts

    def _run(
        self,
        starts: dict[int, _Starts],
        moves: dict[int, tuple[int, tuple[Step, ...]]] | None = None,
    ) -> None:
        """Run, on each site's batch, the start steps of the rows restarted and the moves'
        steps (episode -> (action, steps)) at once; then attach the episodes started."""
        moves = moves or {}
        for pool in self._pools.values():
            work: dict[int, tuple[Step, ...]] = {
                self._episode(k).row: moves[k][1] for k in pool.members if k in moves
            }
            part = starts.get(id(pool))
            if part is not None:
                work.update(dict.fromkeys(part.rows, pool.site.start))
            execute_rows(pool.batch, work)
        for part in starts.values():
            for k, steps in part.episodes.items():
                episode = self._episode(k)
                episode.attach(part.pool.batch, int(self._active[k]), steps, part.pool.known)

    def _next_seeds(self, k: int) -> list[int]:
        """The noise seeds of episode ``k``'s next :data:`SPARES` episodes if it starts
        again by itself, on the same site (none where the next site is another)."""
        return self.envs[k].next_trial_seeds(SPARES)

    def _pool_of(self, episode: Episode) -> _Pool:
        """The pool of ``episode``'s site (made when it is the first on the site)."""
        site = episode.planner.memo
        pool = self._pools.get(id(site))
        if pool is None:
            batch = BatchRun(episode.planner.plan, [0] * ((SPARES + 1) * self.num_envs))
            pool = self._pools[id(site)] = _Pool(site, batch, episode.knowledge_of(batch))
        return pool

    def _episode(self, k: int) -> Episode:
        """Episode ``k`` (started: the vector resets every episode first)."""
        episode = self.envs[k].episode
        if episode is None:
            raise RuntimeError("call reset() first")
        return episode

    def _leave(self, k: int) -> None:
        """Episode ``k`` leaves its pool."""
        for pool in self._pools.values():
            pool.members.discard(k)

    # -- steps ---------------------------------------------------------------------------------
    def step(
        self, actions: NDArray[np.int64]
    ) -> tuple[
        dict[str, NDArray[np.float32]],
        NDArray[np.float64],
        NDArray[np.bool_],
        NDArray[np.bool_],
        dict[str, Any],
    ]:
        """Take each episode's move (an episode that ended at the last step is reset
        instead, its action ignored).

        Raises:
            ValueError: ``actions`` is not ``num_envs`` actions, or one is not in the single
                action space (:meth:`twin.envs.moves.MoveLayout.check`, every episode's
                action, ignored or not), or (strict) one is forbidden; nothing changes.
        """
        actions = self._actions(actions)
        rewards = np.zeros(self.num_envs)
        terminated = np.zeros(self.num_envs, dtype=bool)
        truncated = np.zeros(self.num_envs, dtype=bool)
        infos: dict[str, Any] = {}
        resetting = np.flatnonzero(self._autoreset).tolist()
        # Every move is resolved before anything changes: with strict=True a forbidden move
        # raises and leaves the vector as it was.
        resolved = {
            k: self._episode(k).resolve(actions[k])
            for k in range(self.num_envs)
            if k not in resetting
        }
        starts = self._start(resetting, [None] * len(resetting), None) if resetting else {}
        taken: dict[int, tuple[int, tuple[Step, ...]]] = {}
        for k, (action, _) in resolved.items():
            taken[k] = (action, self._episode(k).planner.act(action))
        self._run(starts, taken)
        for k in range(self.num_envs):
            episode = self._episode(k)
            if k in taken:
                action, steps = taken[k]
                reward = episode.account(action, steps)
                rewards[k], terminated[k], info = episode.finish(action, reward, resolved[k][1])
                self._steps[k] += 1
                truncated[k] = (
                    not terminated[k]
                    and self.max_episode_steps is not None
                    and self._steps[k] >= self.max_episode_steps
                )
            else:
                info = episode.info()
            infos = self._add_info(infos, info, k)
        self._autoreset = terminated | truncated
        return self._observations(), rewards, terminated, truncated, infos

    def _actions(self, actions: object) -> list[int]:
        """The episodes' actions, each checked against the single action space.

        Raises:
            ValueError: not ``num_envs`` actions, or one is not in the space.
        """
        if isinstance(actions, np.ndarray) and actions.ndim:
            items = list(actions.reshape(-1))
        elif isinstance(actions, (list, tuple)):
            items = list(actions)
        else:
            items = []
        if len(items) != self.num_envs:
            raise ValueError(
                f"actions {actions!r}: expected {self.num_envs} actions (one an episode, each "
                f"in Discrete({self.single_action_space.n}))"
            )
        checked = []
        for k, action in enumerate(items):
            try:
                checked.append(self.envs[k].layout.check(action))
            except ValueError as exc:
                raise ValueError(f"episode {k}: {exc}") from None
        return checked

    # -- what comes back -----------------------------------------------------------------------
    def _observations(self) -> dict[str, NDArray[np.float32]]:
        """Every episode's observation, those of a site's episodes built at once (their
        rows of its batch)."""
        out: dict[str, NDArray[np.float32]] = {}
        for pool in self._pools.values():
            indices = sorted(pool.members)
            episodes = [self._episode(k) for k in indices]
            part = episodes[0].observations([e.row for e in episodes], episodes)
            for key, values in part.items():
                if key not in out:
                    out[key] = np.zeros((self.num_envs, *values.shape[1:]), dtype=np.float32)
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
