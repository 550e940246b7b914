"""The campaign as a Gymnasium environment: Gymnasium's conventions, masks, determinism,
pickling, rewards."""

from __future__ import annotations

import pickle
import random
import subprocess
import sys
import warnings
from pathlib import Path

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.wrappers import FlattenObservation
from hypothesis import given, settings

import twin.sim  # noqa: F401  (headless rendering)
from tests.twin.envs.test_sites_and_moves import ACTIONS
from twin.envs import ENV_ID, CpsCampaignEnv
from twin.envs.policies import POLICIES, policy_named
from twin.scenario import load_scenario
from twin.scenario.overrides import with_values

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"
CORRIDOR = ROOT / "scenarios" / "corridor.toml"
HALL = ROOT / "scenarios" / "paper_hall.toml"


def rollout(env, seed: int, policy: str = "random", steps: int | None = None):
    """(observations, rewards, infos) of an episode with a seeded policy."""
    obs, info = env.reset(seed=seed)
    actor = POLICIES[policy](env.unwrapped, seed)
    observations, rewards, infos = [obs], [], [info]
    n = 0
    while steps is None or n < steps:
        obs, reward, terminated, truncated, info = env.step(actor(obs, info))
        observations.append(obs)
        rewards.append(reward)
        infos.append(info)
        n += 1
        if terminated or truncated:
            break
    return observations, rewards, infos


def same(a, b) -> bool:
    """Whether two observations (or infos) are equal, arrays bit for bit."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray):
        return np.array_equal(a, b)
    return a == b


def test_registered_from_a_fresh_interpreter():
    code = (
        "import gymnasium\n"
        f"env = gymnasium.make('twin.envs:{ENV_ID}', scenario={str(SMOKE)!r})\n"
        "obs, info = env.reset(seed=1)\n"
        "assert env.observation_space.contains(obs)\n"
        "assert env.spec.max_episode_steps == 400, env.spec\n"
        "print(env.unwrapped.metadata['render_modes'])\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=ROOT
    )
    assert done.returncode == 0, done.stderr
    assert "rgb_array" in done.stdout


def test_check_env_passes_without_warnings():
    env = gymnasium.make(f"twin.envs:{ENV_ID}", scenario=SMOKE, render_mode="rgb_array").unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env)
    frame = env.render()
    assert frame.dtype == np.uint8
    assert frame.ndim == 3
    assert frame.shape[2] == 3
    env.close()


def test_a_scenario_with_accuracy_stops_runs():
    # campaign.data_stops = "accuracy": the episode's trial replays stops that show only
    # some LEDs; the paper's moves calibrate the camera at a lower predicted error.
    predicted = {}
    for stops in ("all_leds", "accuracy"):
        scenario = with_values(load_scenario(SMOKE), {"campaign.data_stops": stops})
        env = gymnasium.make(f"twin.envs:{ENV_ID}", scenario=scenario).unwrapped
        # The smoke room as it is ("all_leds") passes check_env in the test above.
        if stops == "accuracy":
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                check_env(env)
        _, _, infos = rollout(env, 7, policy="paper")
        assert infos[-1]["camera_errors_mm"], "the smoke room's camera is calibrated"
        predicted[stops] = np.mean([s.predicted_error for s in env.camera_states()])
        env.close()
    assert predicted["accuracy"] < 0.5 * predicted["all_leds"], predicted


def test_metadata_declares_headless_modes_and_autoreset():
    meta = CpsCampaignEnv.metadata
    assert meta["render_modes"] == ["rgb_array"]
    assert meta["render_fps"] > 0
    assert isinstance(meta["autoreset_mode"], gymnasium.vector.AutoresetMode)


def test_same_seed_same_rollout_whatever_the_global_random_state():
    a = gymnasium.make(f"twin.envs:{ENV_ID}", scenario=CORRIDOR)
    b = gymnasium.make(f"twin.envs:{ENV_ID}", scenario=CORRIDOR)
    np.random.seed(1)  # noqa: NPY002  (the global state must not matter)
    random.seed(1)
    first = rollout(a, 11)
    np.random.seed(2)  # noqa: NPY002
    random.seed(2)
    np.random.standard_normal(100)  # noqa: NPY002
    second = rollout(b, 11)
    assert len(first[0]) == len(second[0])
    assert all(same(x, y) for x, y in zip(first[0], second[0], strict=True))
    assert first[1] == second[1]
    for x, y in zip(first[2], second[2], strict=True):
        assert same(x, y)
    # Reseeding the same environment replays it.
    again = rollout(a, 11)
    assert all(same(x, y) for x, y in zip(first[0], again[0], strict=True))
    # Another seed gives other noise.
    other = rollout(a, 12, policy="paper")
    paper = rollout(b, 11, policy="paper")
    assert other[2][-1]["parent_error_mm"] != paper[2][-1]["parent_error_mm"]
    a.close()
    b.close()


def test_observations_lie_in_the_space_and_flatten():
    env = CpsCampaignEnv(CORRIDOR)
    flat = FlattenObservation(CpsCampaignEnv(CORRIDOR))
    for seed in range(3):
        observations, _, infos = rollout(env, seed)
        for obs in observations:
            assert env.observation_space.contains(obs)
        for info in infos:
            assert {
                "camera_errors_mm",
                "parent_error_mm",
                "distance_m",
                "time_s",
                "action_mask",
            } <= info.keys()
        obs, _ = flat.reset(seed=seed)
        assert flat.observation_space.contains(obs)
        assert obs.ndim == 1
    env.close()
    flat.close()


def test_pickling_round_trips_mid_episode():
    env = CpsCampaignEnv(CORRIDOR)
    obs, info = env.reset(seed=4)
    actor = policy_named("paper")(env, 4)
    for _ in range(3):
        obs, *_, info = env.step(actor(obs, info))
    copy = pickle.loads(pickle.dumps(env))
    assert same(copy.episode.observation(), obs)
    assert same(copy.episode.info()["action_mask"], info["action_mask"])
    while True:
        action = actor(obs, info)
        a, b = env.step(action), copy.step(action)
        assert same(a[0], b[0])
        assert a[1:4] == b[1:4]
        obs, info = a[0], a[4]
        if a[2]:
            break
    env.close()
    copy.close()


def without_reference(path: Path):
    """The scenario at ``path`` without its reference data sets: they are taken before the
    first move, and each copy of an episode that plays a move no episode played before
    takes them again (two thirds of the corridor's moves' time)."""
    return with_values(load_scenario(path), {"campaign.reference_cameras": []})


def test_every_allowed_move_executes_as_asked():
    env = CpsCampaignEnv(without_reference(CORRIDOR))
    obs, info = env.reset(seed=2)
    actor = policy_named("paper")(env, 2)
    decisions = set()
    for _ in range(6):
        decisions.add(info["decision"])
        for action in np.flatnonzero(info["action_mask"]):
            trial = pickle.loads(pickle.dumps(env))
            _, _, _, _, after = trial.step(int(action))
            assert "fallback" not in after
            assert after["move"] == env.layout.describe(int(action))
            trial.close()
        obs, _, terminated, _, info = env.step(actor(obs, info))
        if terminated:
            break
    assert decisions == {"leg", "visit"}
    env.close()


def test_a_forbidden_move_runs_its_fallback_and_strict_raises():
    env = CpsCampaignEnv(CORRIDOR)
    _obs, info = env.reset(seed=3)
    layout = env.layout
    forbidden = int(np.flatnonzero(~info["action_mask"])[0])
    expected = layout.fallback(forbidden, info["action_mask"])
    _, _, _, _, after = env.step(forbidden)
    assert after["fallback"]["requested"] == forbidden
    assert after["fallback"]["taken"] == expected
    assert after["move"] == layout.describe(expected)
    assert after["fallbacks"] == 1
    strict = CpsCampaignEnv(CORRIDOR, strict=True)
    _, info = strict.reset(seed=3)
    with pytest.raises(ValueError, match="not allowed now"):
        strict.step(int(np.flatnonzero(~info["action_mask"])[0]))
    env.close()
    strict.close()


# Outside the action space, strict or not: refused, naming the action and the space, and the
# episode goes on as if it had not been asked.
NOT_ACTIONS = (
    32,
    27,
    -1,
    0.5,
    13.7,
    3.0,
    True,
    False,
    np.bool_(True),
    np.float64(2.0),
    np.array([1]),
    np.array(2.0),
    "3",
    None,
    2**64,
)


@pytest.mark.parametrize("strict", [False, True])
def test_an_action_outside_the_space_is_refused(strict):
    env = CpsCampaignEnv(SMOKE, strict=strict)
    _, info = env.reset(seed=4)
    size = env.action_space.n
    before, steps = env.action_masks(), env.plan.steps
    for action in NOT_ACTIONS:
        with pytest.raises(ValueError, match="action space") as raised:
            env.step(action)
        message = str(raised.value)
        assert f"action {action!r} is" in message
        assert f"action space Discrete({size})" in message
    # The planner the environment plays refuses them too.
    for action in (0.5, True, size):
        with pytest.raises(ValueError, match=rf"action space Discrete\({size}\)"):
            env.planner.act(action)
    assert np.array_equal(env.action_masks(), before)
    assert env.plan.steps == steps
    assert info["fallbacks"] == env.episode.info()["fallbacks"] == 0
    # Integers of numpy's kinds are actions: the same move as the Python int.
    allowed = int(np.flatnonzero(before)[0])
    for action in (np.int64(allowed), np.array(allowed), np.uint8(allowed)):
        twin = CpsCampaignEnv(SMOKE, strict=strict)
        twin.reset(seed=4)
        _, _, _, _, after = twin.step(action)
        assert after["move"] == env.layout.describe(allowed)
        assert "fallback" not in after
        twin.close()
    env.close()


@pytest.fixture(scope="module")
def stepped():
    """One environment for every example, and the plan's steps after its reset."""
    env = CpsCampaignEnv(SMOKE)
    env.reset(seed=4)
    yield env, env.plan.steps
    env.close()


@settings(max_examples=40, deadline=None)
@given(ACTIONS)
def test_a_step_takes_an_action_of_the_space_or_refuses_it(stepped, labelled):
    action, index = labelled
    env, start = stepped
    _, info = env.reset(seed=4)
    mask = info["action_mask"]
    if index is None:
        with pytest.raises(ValueError, match=r"the action space Discrete\(\d+\)"):
            env.step(action)
        assert env.plan.steps == start  # refused before anything changed
        return
    _, _, _, _, after = env.step(action)
    # A move inside the space that is forbidden now falls back, as documented.
    taken = index if mask[index] else env.layout.fallback(index, mask)
    assert after["move"] == env.layout.describe(taken)
    assert ("fallback" in after) == (not mask[index])
    if not mask[index]:
        assert after["fallback"]["requested"] == index


def test_reset_options_are_named_when_wrong():
    env = CpsCampaignEnv(SMOKE)
    with pytest.raises(ValueError, match=r"unknown reset option 'bogus'; known options: scenario"):
        env.reset(seed=0, options={"bogus": 1})
    with pytest.raises(ValueError, match=r"reset options \[1, 2\]: expected a dict .* got list"):
        env.reset(seed=0, options=[1, 2])
    with pytest.raises(ValueError, match=r"scenario 7: expected a scenario file"):
        env.reset(seed=0, options={"scenario": 7})
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0)  # nothing was started
    env.reset(seed=0, options={})
    assert env.scenario.name == "smoke"
    env.close()


def test_action_masks_matches_the_info():
    env = CpsCampaignEnv(SMOKE)
    _, info = env.reset(seed=0)
    assert np.array_equal(env.action_masks(), info["action_mask"])
    assert env.action_masks().dtype == bool
    assert env.action_masks().shape == (env.layout.size,)
    env.close()


@pytest.mark.parametrize("planner", ["campaign", "stands"])
@pytest.mark.parametrize("mode", ["sync", "async"])
def test_vector_environments(mode, planner):
    envs = gymnasium.make_vec(
        f"twin.envs:{ENV_ID}",
        num_envs=2,
        vectorization_mode=mode,
        scenario=str(SMOKE),
        planner=planner,
    )
    try:
        obs, info = envs.reset(seed=[5, 6])
        assert envs.observation_space.contains(obs)
        rng = np.random.default_rng(0)
        for _ in range(6):
            masks = info["action_mask"]
            # After its last step an episode allows nothing; the next step resets it.
            actions = np.array([rng.choice(np.flatnonzero(m)) if m.any() else 0 for m in masks])
            obs, rewards, _terminated, _truncated, info = envs.step(actions)
            assert rewards.shape == (2,)
            assert envs.observation_space.contains(obs)
    finally:
        envs.close()


def test_truth_reward_is_the_mean_true_camera_error_at_the_end():
    env = CpsCampaignEnv(SMOKE, reward_mode="truth", uncalibrated_error_mm=500.0)
    _, rewards, infos = rollout(env, 7, policy="paper")
    assert all(r == 0.0 for r in rewards[:-1])
    errors = infos[-1]["camera_errors_mm"]
    assert errors, "the smoke room's camera is calibrated"
    assert rewards[-1] == pytest.approx(-np.mean(list(errors.values())))
    # An episode that ends at once counts the camera as not calibrated.
    env.reset(seed=7)
    _, reward, terminated, _, _ = env.step(env.layout.end)
    assert terminated
    assert reward == -500.0
    env.close()


def test_predicted_reward_is_the_decrease_of_the_predicted_error_less_the_travel():
    env = CpsCampaignEnv(SMOKE, cost_per_m=2.0, cost_per_s=0.0, uncalibrated_error_mm=800.0)
    _, rewards, infos = rollout(env, 8, policy="paper")
    predicted = np.mean([s.predicted_error for s in env.camera_states()]) * 1e3
    travel = infos[-1]["distance_m"]
    # The rewards telescope: the error fell from 800 mm to the calibration's prediction.
    assert sum(rewards) == pytest.approx(800.0 - predicted - 2.0 * travel)
    env.close()


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match="reward_mode"):
        CpsCampaignEnv(SMOKE, reward_mode="fast")
    with pytest.raises(ValueError, match="render_mode"):
        CpsCampaignEnv(SMOKE, render_mode="human")
    with pytest.raises(ValueError, match="budget_m"):
        CpsCampaignEnv(SMOKE, budget_m=-1.0)
    with pytest.raises(ValueError, match="cost_per_m"):
        CpsCampaignEnv(SMOKE, cost_per_m=float("nan"))
    with pytest.raises(ValueError, match="max_cameras"):
        CpsCampaignEnv(SMOKE, max_cameras=0)
    with pytest.raises(ValueError, match="uncalibrated_error_mm"):
        CpsCampaignEnv(SMOKE, uncalibrated_error_mm=-1.0)
    with pytest.raises(ValueError, match="max_stations"):
        CpsCampaignEnv(SMOKE, max_stations=0)
    too_small = CpsCampaignEnv(HALL, max_cameras=2)
    with pytest.raises(ValueError, match="3 cameras, more than max_cameras = 2"):
        too_small.reset(seed=0)
    too_few = CpsCampaignEnv(HALL, max_stations=2)
    with pytest.raises(ValueError, match="5 stations, more than max_stations = 2"):
        too_few.reset(seed=0)
    env = CpsCampaignEnv(SMOKE)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0)
    with pytest.raises(ValueError, match="unknown policy"):
        policy_named("clever")
    env.close()


def test_reset_options_choose_the_site():
    env = CpsCampaignEnv(SMOKE)
    env.reset(seed=0, options={"scenario": CORRIDOR})
    assert env.scenario.name == "corridor"
    env.reset(seed=0, options={"scenario": "random"})
    first = env.scenario.name
    env.reset(seed=0, options={"scenario": "random"})
    assert env.scenario.name == first
    env.reset(seed=1, options={"scenario": "random"})
    assert env.scenario.name != first
    env.reset(seed=0)
    assert env.scenario.name == "smoke"
    env.close()
