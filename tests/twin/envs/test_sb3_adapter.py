"""The Stable-Baselines3 ``VecEnv`` logic over the environment's vector, without torch:
an episode that ends is reset in the same step, its last observation in the info; the
masks as MaskablePPO reads them; episodes reset one by one. Each episode is the single
environment's, bit for bit."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import numpy as np
import pytest

import twin.sim  # noqa: F401  (headless rendering)
from twin.envs import CpsCampaignEnv
from twin.envs.sb3 import CampaignVecAdapter

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


def _row(obs: dict, k: int) -> dict:
    return {key: v[k] for key, v in obs.items()}


def test_the_adapter_imports_neither_torch_nor_stable_baselines3(monkeypatch):
    # A module set to None in sys.modules cannot be imported: the adapter must not try.
    monkeypatch.setitem(sys.modules, "torch", None)
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)
    monkeypatch.delitem(sys.modules, "twin.envs.sb3", raising=False)
    module = importlib.import_module("twin.envs.sb3")
    assert module.CampaignVecAdapter.__mro__[1] is object
    with pytest.raises(ImportError):
        module.make_sb3_vec_env(1, scenario=SMOKE)


def test_episodes_end_and_restart_in_the_same_step_as_the_single_environment():
    n = 2
    venv = CampaignVecAdapter(n, scenario=SMOKE, planner="stands")
    singles = [CpsCampaignEnv(SMOKE, planner="stands") for _ in range(n)]
    assert venv.seed(40) == [40, 41]
    obs = venv.reset()
    expected = [env.reset(seed=40 + k)[0] for k, env in enumerate(singles)]
    for k in range(n):
        assert _same(_row(obs, k), expected[k])
        assert obs["parent"].dtype == np.float32
    rng = np.random.default_rng(0)
    ended = 0
    for _ in range(40):
        masks = np.stack(venv.env_method("action_masks"))
        assert masks.shape == (n, venv.action_space.n)
        assert masks.any(axis=1).all(), "never an all-False mask"
        np.testing.assert_array_equal(masks, venv.action_masks())
        actions = np.array([rng.choice(np.flatnonzero(m)) for m in masks])
        obs, rewards, dones, infos = venv.step(actions)
        assert isinstance(infos, list)
        assert rewards.dtype == np.float32
        for k, env in enumerate(singles):
            last, reward, terminated, truncated, _ = env.step(int(actions[k]))
            assert rewards[k] == np.float32(reward)
            assert dones[k] == (terminated or truncated)
            if dones[k]:
                ended += 1
                assert _same(infos[k]["terminal_observation"], last)
                assert infos[k]["TimeLimit.truncated"] is False
                last, _ = env.reset()  # the next episode, from the same generator
            else:
                assert "terminal_observation" not in infos[k]
            assert _same(_row(obs, k), last)
    assert ended >= 4, "the smoke room's episodes are a few moves long"
    venv.close()


def test_the_step_limit_truncates_and_restarts():
    venv = CampaignVecAdapter(1, max_episode_steps=2, scenario=SMOKE, planner="stands")
    venv.seed(3)
    venv.reset()
    layout = venv.get_attr("layout")[0]
    _, _, dones, infos = venv.step(np.array([layout.go_to(0)]))
    assert not dones[0]
    mask = venv.env_method("action_masks", indices=0)[0]
    _, _, dones, infos = venv.step(np.array([np.flatnonzero(mask)[0]]))
    assert dones[0]
    assert infos[0]["TimeLimit.truncated"] is True
    assert venv.get_attr("episode")[0].moves == [], "a new episode has begun"
    venv.close()


def test_single_episodes_reset_through_a_public_method():
    venv = CampaignVecAdapter(3, scenario=SMOKE, planner="stands")
    single = CpsCampaignEnv(SMOKE, planner="stands")
    venv.seed(7)
    obs = venv.reset()
    single.reset(seed=8)
    layout = venv.get_attr("layout", indices=[0])[0]
    obs, *_ = venv.step(np.full(3, layout.go_to(0)))
    single.step(layout.go_to(0))
    before = [_row(obs, k) for k in range(3)]
    obs = venv.reset_episodes([1])
    expected, _ = single.reset()
    assert _same(_row(obs, 1), expected)
    assert _same(_row(obs, 0), before[0])
    assert _same(_row(obs, 2), before[2])
    assert [len(e.moves) for e in venv.get_attr("episode")] == [1, 0, 1]
    assert venv.env_is_wrapped(object) == [False, False, False]
    with pytest.raises(ValueError, match="episode 3"):
        venv.reset_episodes([3])
    with pytest.raises(ValueError, match="distinct"):
        venv.venv.reset_episodes([0, 0])
    venv.close()
