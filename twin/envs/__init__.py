"""Gymnasium environments: the campaign with an agent choosing the robot group's moves.

Importing this package registers ``camnet/CpsCampaign-v0`` (:class:`CpsCampaignEnv`), so
``gymnasium.make("twin.envs:camnet/CpsCampaign-v0", scenario=...)`` works from a fresh
interpreter; ``gymnasium.make_vec`` gives :class:`twin.envs.vector.CpsCampaignVectorEnv`
(episodes that share their moves share their batch), or with ``vectorization_mode="sync"``
or ``"async"`` Gymnasium's own vectors.

The package imports the environment (and with it MuJoCo) only when it is first used, so
that importing it to register, or to read :data:`POLICY_NAMES`, needs no OpenGL.
"""

from __future__ import annotations

from typing import Any

from gymnasium.envs.registration import register, registry

from twin.envs.moves import FORMATIONS, MoveLayout

__all__ = [
    "ENV_ID",
    "FORMATIONS",
    "MAX_EPISODE_STEPS",
    "POLICY_NAMES",
    "CpsCampaignEnv",
    "MoveLayout",
]

ENV_ID = "camnet/CpsCampaign-v0"
"""The environment's registered id."""

MAX_EPISODE_STEPS = 400
"""Decisions before an episode is truncated (the paper's hall takes about 40)."""

POLICY_NAMES = ("paper", "side_by_side", "greedy", "random")
"""The baseline policies of :mod:`twin.envs.policies`, by name."""

if ENV_ID not in registry:
    register(
        id=ENV_ID,
        entry_point="twin.envs.campaign_env:CpsCampaignEnv",
        vector_entry_point="twin.envs.vector:CpsCampaignVectorEnv",
        max_episode_steps=MAX_EPISODE_STEPS,
    )


def __getattr__(name: str) -> Any:
    if name == "CpsCampaignEnv":
        from twin.envs.campaign_env import CpsCampaignEnv

        return CpsCampaignEnv
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
