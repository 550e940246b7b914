"""MaskablePPO (sb3-contrib) learns through the environment: on one environment's raw
observation (``MultiInputPolicy`` on the Dict), and through the project's vector as
Stable-Baselines3's ``VecEnv`` (:func:`twin.envs.sb3.make_sb3_vec_env`). Run by
``make test-rl`` (torch and sb3-contrib in .venv-rl); ``make test`` leaves this folder out.

Every move is checked against the mask the environment gave before it (a forbidden move
would also raise: the environments are strict), and the vector's episodes are counted three
ways (its dones, its terminal observations, Stable-Baselines3's monitor)."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

pytest.importorskip("sb3_contrib")  # make test-rl installs it; nothing here runs without

import torch
from sb3_contrib import MaskablePPO
from sb3_contrib.common.maskable.utils import get_action_masks
from stable_baselines3.common.vec_env import VecEnvWrapper, VecMonitor

import twin.envs  # noqa: F401  (registers the environment)
from twin.envs.heldout import TRAINING_SEEDS
from twin.envs.sb3 import make_sb3_vec_env

SCENARIO = "smoke"
"""A small site (one camera): episodes of a few moves, so a few thousand steps see many."""

PPO = {"n_steps": 256, "batch_size": 64, "n_epochs": 2, "seed": 0, "device": "cpu"}
"""Short rollouts: several updates in the steps the tests take."""


@pytest.fixture(autouse=True)
def one_thread():
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


class MaskChecked(gymnasium.Wrapper):
    """Records, for every move, whether the mask the environment gave before it allowed it."""

    def __init__(self, env: gymnasium.Env) -> None:
        super().__init__(env)
        self.allowed: list[bool] = []
        self.episodes = 0

    def step(self, action):
        self.allowed.append(bool(self.env.unwrapped.action_masks()[int(action)]))
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.episodes += bool(terminated or truncated)
        return obs, reward, terminated, truncated, info


def test_maskable_ppo_learns_on_the_raw_observation():
    env = MaskChecked(
        gymnasium.make("camnet/CpsCampaign-v0", scenario=SCENARIO, planner="stands", strict=True)
    )
    assert isinstance(env.observation_space, gymnasium.spaces.Dict)
    assert all(s.dtype == np.float32 for s in env.observation_space.values())
    model = MaskablePPO("MultiInputPolicy", env, **PPO)
    model.learn(total_timesteps=2048)
    steps = len(env.allowed)
    assert steps >= 2048
    assert all(env.allowed), f"{steps - sum(env.allowed)} masked moves taken"
    assert env.episodes >= 20  # smoke's episodes take a few moves
    # The trained policy, asked with the environment's masks, picks allowed moves only.
    obs, info = env.reset(seed=TRAINING_SEEDS.start)
    for _ in range(50):
        mask = info["action_mask"]
        action, _ = model.predict(obs, action_masks=mask, deterministic=True)
        assert mask[int(action)]
        obs, _, terminated, truncated, info = env.step(int(action))
        if terminated or truncated:
            obs, info = env.reset()
    # And the masks reach the policy: every move masked but one gives that one.
    obs, info = env.reset(seed=1)
    only = np.zeros_like(info["action_mask"])
    only[np.flatnonzero(info["action_mask"])[-1]] = True
    for _ in range(5):
        action, _ = model.predict(obs, action_masks=only, deterministic=False)
        assert int(action) == int(np.flatnonzero(only)[0])


class Checked(VecEnvWrapper):
    """Checks each vector step: every move allowed by the masks MaskablePPO read
    (``env_method("action_masks")``), and each ended episode's terminal observation and its
    reset in the same step (the observation returned is the next episode's first)."""

    def __init__(self, venv) -> None:
        super().__init__(venv)
        self.moves = 0
        self.masked = 0
        self.ended = 0
        self.terminal = 0
        self.masks_all_false = 0

    def reset(self):
        return self.venv.reset()

    def step_async(self, actions):
        masks = np.stack(self.venv.env_method("action_masks"))
        assert masks.shape == (self.num_envs, self.action_space.n)
        self.masks_all_false += int((~masks.any(axis=1)).sum())
        self.masked += int((~masks[np.arange(self.num_envs), actions]).sum())
        self.moves += self.num_envs
        self.venv.step_async(actions)

    def step_wait(self):
        obs, rewards, dones, infos = self.venv.step_wait()
        for k in np.flatnonzero(dones):
            last = infos[k]["terminal_observation"]
            assert self.observation_space.contains(last)
            assert obs["travel"][k][0] == 0.0  # the next episode's first: no travel yet
            self.terminal += 1
        self.ended += int(dones.sum())
        assert self.observation_space.contains({key: v[0] for key, v in obs.items()})
        return obs, rewards, dones, infos


def test_maskable_ppo_learns_through_the_projects_vec_env():
    n = 8
    venv = make_sb3_vec_env(n, scenario=SCENARIO, planner="stands", strict=True)
    venv.seed(TRAINING_SEEDS.start)
    checked = Checked(venv)
    monitored = VecMonitor(checked)
    model = MaskablePPO("MultiInputPolicy", monitored, **{**PPO, "n_steps": 128})
    model.learn(total_timesteps=4096)
    assert checked.moves >= 4096
    assert checked.masked == 0
    assert checked.masks_all_false == 0  # an ended episode is reset in the same step
    # Every episode that ended gave its terminal observation, and the monitor counted it.
    assert checked.ended == checked.terminal >= 2 * n
    assert checked.ended == monitored.episode_count
    masks = get_action_masks(monitored)
    assert masks.shape == (n, venv.action_space.n)
    assert masks.any(axis=1).all()
    monitored.close()


def test_twin_strategies_evaluates_a_saved_model_on_a_test_set(tmp_path, capsys):
    """A model saved after a few updates plays the smoke test set through ``twin strategies
    --policy model.zip --baseline greedy`` (loaded once, its moves masked); one trained with
    room for fewer stations is refused, naming the model."""
    import csv

    from twin.cli import main

    env = gymnasium.make("camnet/CpsCampaign-v0", scenario=SCENARIO, planner="stands")
    model = MaskablePPO("MultiInputPolicy", env, **PPO)
    model.learn(total_timesteps=256)
    path = tmp_path / "model.zip"
    model.save(path)
    out = tmp_path / "eval"
    argv = ["strategies", "--test-set", "smoke", "--policy", str(path), "--baseline", "greedy"]
    assert main([*argv, "--planner", "stands", "--out", str(out)]) == 0
    rows = list(csv.DictReader((out / "episodes.csv").open()))
    assert [r["policy"] for r in rows] == ["greedy"] * 3 + [str(path)] * 3
    assert all(int(r["steps"]) >= 1 for r in rows)
    differences = list(csv.DictReader((out / "differences.csv").open()))
    assert {d["policy"] for d in differences} == {str(path)}
    assert all(d["pairs"] == "3" for d in differences if d["metric"] != "mean_camera_error_mm")

    small = gymnasium.make("camnet/CpsCampaign-v0", scenario=SCENARIO, max_stations=4)
    other = tmp_path / "other.zip"
    MaskablePPO("MultiInputPolicy", small, **PPO).save(other)
    capsys.readouterr()
    argv = ["strategies", "--test-set", "smoke", "--policy", str(other)]
    assert main([*argv, "--out", str(tmp_path / "o")]) == 2
    said = " ".join(capsys.readouterr().out.split())
    assert f"policy {other}: the model's observation or action space is not the" in said
    assert not (tmp_path / "o").exists()
