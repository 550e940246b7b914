"""The environment's own vector: episodes that share their moves share their batch, and
every episode is the single environment's, bit for bit."""

from __future__ import annotations

import re
from pathlib import Path

import gymnasium
import numpy as np
import pytest

import twin.sim  # noqa: F401  (headless rendering)
from twin.envs import ENV_ID, CpsCampaignEnv
from twin.envs.policies import policy_named
from twin.envs.vector import CpsCampaignVectorEnv

from .test_campaign_env import without_reference

ROOT = Path(__file__).resolve().parents[3]
CORRIDOR = ROOT / "scenarios" / "corridor.toml"
SMOKE = ROOT / "scenarios" / "smoke.toml"


def _row(obs: dict, k: int) -> dict:
    return {key: value[k] for key, value in obs.items()}


def _equal(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


@pytest.mark.parametrize("planner", ["campaign", "stands"])
@pytest.mark.parametrize("policy", ["random", "paper"])
def test_each_episode_is_the_single_environments(policy, planner):
    n = 4
    # The random moves, each new one a campaign run again from its start, on the corridor
    # without its reference data sets (taken before the first move: most of the time); the
    # paper's moves on the corridor as it is.
    site = without_reference(CORRIDOR) if policy == "random" else CORRIDOR
    vector = gymnasium.make_vec(f"twin.envs:{ENV_ID}", num_envs=n, scenario=site, planner=planner)
    assert isinstance(vector.unwrapped, CpsCampaignVectorEnv)
    singles = [CpsCampaignEnv(site, planner=planner) for _ in range(n)]
    obs, info = vector.reset(seed=20)
    single = [env.reset(seed=20 + k) for k, env in enumerate(singles)]
    for k in range(n):
        assert _equal(_row(obs, k), single[k][0])
    actors = [policy_named(policy)(env, k) for k, env in enumerate(singles)]
    done = np.zeros(n, dtype=bool)
    for _ in range(60):
        actions = np.array(
            [0 if done[k] else actors[k](single[k][0], single[k][-1]) for k in range(n)]
        )
        obs, rewards, terminated, truncated, info = vector.step(actions)
        assert len(vector.unwrapped._pools) == 1  # one site: one batch
        for k, env in enumerate(singles):
            if done[k]:  # the vector reset it and ignored the action
                single[k] = env.reset()
                actors[k] = policy_named(policy)(env, k)
                assert _equal(_row(obs, k), single[k][0])
                continue
            single[k] = env.step(int(actions[k]))
            o, r, term, trunc, inf = single[k]
            assert _equal(_row(obs, k), o)
            assert rewards[k] == r
            assert terminated[k] == term
            assert truncated[k] == trunc
            assert np.array_equal(info["action_mask"][k], inf["action_mask"])
        done = terminated | truncated
    vector.close()
    for env in singles:
        env.close()


def test_truncation_and_bad_seeds():
    vector = CpsCampaignVectorEnv(2, max_episode_steps=2, scenario=SMOKE)
    _, info = vector.reset(seed=[1, 2])
    masks = info["action_mask"]
    # Travel moves keep the campaign going: the second step truncates it.
    actions = np.array([np.flatnonzero(m)[0] for m in masks])
    for _ in range(2):
        _, _, terminated, truncated, info = vector.step(actions)
        actions = np.array([np.flatnonzero(m)[0] if m.any() else 0 for m in info["action_mask"]])
    assert truncated.all()
    assert not terminated.any()
    with pytest.raises(ValueError, match="3 seeds for 2 environments"):
        vector.reset(seed=[1, 2, 3])
    with pytest.raises(ValueError, match="num_envs"):
        CpsCampaignVectorEnv(0, scenario=SMOKE)
    assert vector.action_masks().shape == (2, vector.single_action_space.n)
    vector.close()


def test_a_strict_refusal_leaves_the_vector_as_it_was():
    strict = CpsCampaignVectorEnv(2, strict=True, scenario=CORRIDOR)
    plain = CpsCampaignVectorEnv(2, scenario=CORRIDOR)
    _, info = strict.reset(seed=5)
    plain.reset(seed=5)
    masks = info["action_mask"]
    allowed = np.array([np.flatnonzero(m)[0] for m in masks])
    forbidden = allowed.copy()
    forbidden[1] = np.flatnonzero(~masks[1])[0]
    with pytest.raises(ValueError, match="not allowed now"):
        strict.step(forbidden)
    a, b = strict.step(allowed), plain.step(allowed)
    for k in range(2):
        assert _equal(_row(a[0], k), _row(b[0], k))
    assert np.array_equal(a[1], b[1])
    strict.close()
    plain.close()


def test_actions_outside_the_space_and_bad_options_leave_the_vector_as_it_was():
    vector = CpsCampaignVectorEnv(2, scenario=SMOKE)
    plain = CpsCampaignVectorEnv(2, scenario=SMOKE)
    _, info = vector.reset(seed=5)
    plain.reset(seed=5)
    n = vector.single_action_space.n
    allowed = np.array([np.flatnonzero(m)[0] for m in info["action_mask"]])
    bad = {
        "32": [int(allowed[0]), 32],
        "np.int64(-1)": np.array([-1, allowed[1]]),
        "0.5": [int(allowed[0]), 0.5],
        "True": [True, int(allowed[1])],
        "np.float64(2.0)": np.array([2.0, 1.0]),
    }
    for shown, actions in bad.items():
        pattern = rf"episode \d: action {re.escape(shown)} is .*Discrete\({n}\)"
        with pytest.raises(ValueError, match=pattern):
            vector.step(actions)
    for actions in ([int(allowed[0])], allowed[0], np.array([allowed, allowed])):
        with pytest.raises(ValueError, match=rf"expected 2 actions .*Discrete\({n}\)"):
            vector.step(actions)
    with pytest.raises(ValueError, match="unknown reset option 'bogus'; known options: scenario"):
        vector.reset(seed=5, options={"bogus": 1})
    with pytest.raises(ValueError, match=r"reset options \[1, 2\]: expected a dict"):
        vector.reset(seed=5, options=[1, 2])
    # Integers of numpy's kinds and Python's are actions.
    a = vector.step([np.int32(allowed[0]), int(allowed[1])])
    b = plain.step(allowed)
    for k in range(2):
        assert _equal(_row(a[0], k), _row(b[0], k))
    assert np.array_equal(a[1], b[1])
    vector.close()
    plain.close()
