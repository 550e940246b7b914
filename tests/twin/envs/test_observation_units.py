"""The observation as a learning library reads it: keys that are no attribute of torch's
``nn.Module``, float32 values within bounds that mean something, in the units
:data:`twin.envs.observation.ENTRIES` states."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import twin.sim  # noqa: F401  (headless rendering)
from twin.envs import CpsCampaignEnv
from twin.envs.free_space import MAX_RANGE
from twin.envs.observation import ENTRIES, ERROR_SCALE_M, POSE_SCALE, SiteScale
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"

# The public attributes of torch.nn.Module (torch 2.x) and of nn.ModuleDict, which
# Stable-Baselines3's CombinedExtractor fills with a module per observation key: a key
# that is one of these is refused ("attribute 'children' already exists").
TORCH_MODULE_NAMES = frozenset(
    [
        "T_destination",
        "add_module",
        "apply",
        "bfloat16",
        "buffers",
        "call_super_init",
        "children",
        "compile",
        "cpu",
        "cuda",
        "double",
        "dump_patches",
        "eval",
        "extra_repr",
        "float",
        "forward",
        "get_buffer",
        "get_extra_state",
        "get_parameter",
        "get_submodule",
        "half",
        "ipu",
        "load_state_dict",
        "modules",
        "mtia",
        "named_buffers",
        "named_children",
        "named_modules",
        "named_parameters",
        "parameters",
        "register_backward_hook",
        "register_buffer",
        "register_forward_hook",
        "register_forward_pre_hook",
        "register_full_backward_hook",
        "register_full_backward_pre_hook",
        "register_load_state_dict_post_hook",
        "register_load_state_dict_pre_hook",
        "register_module",
        "register_parameter",
        "register_state_dict_post_hook",
        "register_state_dict_pre_hook",
        "requires_grad_",
        "set_extra_state",
        "set_submodule",
        "share_memory",
        "state_dict",
        "to",
        "to_empty",
        "train",
        "training",
        "type",
        "xpu",
        "zero_grad",
        "clear",
        "items",
        "keys",
        "pop",
        "update",
        "values",
    ]
)


def test_no_key_is_an_attribute_of_a_torch_module():
    env = CpsCampaignEnv(SMOKE)
    keys = set(env.observation_space.spaces)
    assert keys == set(ENTRIES)
    assert not keys & TORCH_MODULE_NAMES
    assert all(k.isidentifier() and not k.startswith("_") for k in keys)


def test_the_space_is_float32_with_bounds_of_a_few_units():
    space = CpsCampaignEnv(SMOKE, max_cameras=3, max_stations=4).observation_space
    for key, box in space.spaces.items():
        assert box.dtype == np.float32, key
        assert np.isfinite(box.low).all(), key
        assert np.isfinite(box.high).all(), key
        assert (box.low < box.high).all(), key
        assert np.abs(box.low).max() <= 100.0, key
        assert np.abs(box.high).max() <= 100.0, key


def test_observations_are_in_the_stated_units():
    # The smoke room's parent starts at (0, 0) facing +x; its estimate at the reset is
    # the total station's fix, within millimetres of it. The floor's centre and half side
    # give the site units; a camera calibrated shows its predicted error in 50 mm units.
    env = CpsCampaignEnv(SMOKE, planner="stands")
    scenario = load_scenario(SMOKE)
    units = SiteScale.of(scenario.space)
    (x0, x1), (y0, y1) = scenario.space.x_range, scenario.space.y_range
    assert units.half == pytest.approx(max(x1 - x0, y1 - y0) / 2)
    obs, info = env.reset(seed=1)
    for value in obs.values():
        assert value.dtype == np.float32
    expected = (np.zeros(2) - units.centre) / units.half
    np.testing.assert_allclose(obs["parent"][:2], expected, atol=0.01 / units.half)
    np.testing.assert_allclose(obs["parent"][2:], [1.0, 0.0], atol=0.01)
    assert obs["travel"][0] == 0.0
    assert obs["travel"][1] == 1.0, "the whole budget is left"
    assert 0.0 <= obs["travel"][2] < 0.1, "the reference data take minutes, not hours"
    rays = env.episode.free_space.rays(
        env.episode.now().parent_xy[:1], env.episode.now().parent_yaw[:1]
    )
    np.testing.assert_allclose(obs["free_space"], rays[0] / MAX_RANGE, rtol=1e-6)
    std = obs["parent_uncertainty"].diagonal() * POSE_SCALE
    covariance = env.episode.now().parent_covariance[0]
    np.testing.assert_allclose(std, np.sqrt(covariance.diagonal()), rtol=1e-5)
    off = obs["parent_uncertainty"][~np.eye(4, dtype=bool)]
    assert (np.abs(off) <= 1.0).all(), "correlations"
    layout = env.layout
    obs, *_, info = env.step(layout.go_to(0))
    while info["decision"] == "leg":
        obs, *_, info = env.step(int(np.flatnonzero(info["action_mask"])[-1]))
    obs, *_, info = env.step(layout.calibrate)
    state = env.camera_states()[0]
    assert state.calibrated
    assert obs["cameras"][0, 2] * ERROR_SCALE_M == pytest.approx(state.predicted_error, rel=1e-6)
    assert obs["stations"][0, 1] == pytest.approx(1 / env.max_cameras)
    budget = env.planner.budget_m
    assert obs["travel"][0] * budget == pytest.approx(info["distance_m"], rel=1e-6)
    env.close()
