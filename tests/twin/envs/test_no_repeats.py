"""No move repeats for free: a calibration at a station is forbidden until the group has
moved, and any sequence of allowed moves earns at most what the reward's terms allow."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import twin.sim  # noqa: F401  (headless rendering)
from twin.envs import MAX_EPISODE_STEPS, CpsCampaignEnv
from twin.envs.campaign_env import COST_PER_M, COST_PER_S

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"
CORRIDOR = ROOT / "scenarios" / "corridor.toml"
PLANNERS = ("campaign", "stands")


def _arrive(env: CpsCampaignEnv, info: dict, action: int) -> dict:
    """Take ``action`` (a travel), then the last allowed leg until the group arrives."""
    _, _, _, _, info = env.step(action)
    while info["decision"] == "leg":
        _, _, _, _, info = env.step(int(np.flatnonzero(info["action_mask"])[-1]))
    return info


@pytest.mark.parametrize("planner", PLANNERS)
def test_a_calibration_is_not_repeated_until_the_group_has_moved(planner):
    # The corridor: two cameras' stations, cam1's then cam2's.
    env = CpsCampaignEnv(CORRIDOR, planner=planner, strict=True)
    layout = env.layout
    _, info = env.reset(seed=3)
    info = _arrive(env, info, layout.go_to(0))
    assert info["action_mask"][layout.calibrate], "the camera's station: calibrate allowed"
    _, _, _, _, info = env.step(layout.calibrate)
    assert info["decision"] == "visit"
    assert not info["action_mask"][layout.calibrate], "at the same place: no repeat"
    assert info["action_mask"][layout.go_to(1)]
    assert info["action_mask"][layout.end]
    with pytest.raises(ValueError, match="calibrate"):
        env.step(layout.calibrate)
    # To the other station and back: the group has moved, a second visit (a loop closed)
    # may calibrate the camera again.
    info = _arrive(env, info, layout.go_to(1))
    assert info["action_mask"][layout.calibrate], "another camera's station"
    info = _arrive(env, info, layout.go_to(0))
    assert info["action_mask"][layout.calibrate]
    _, _, _, _, info = env.step(layout.calibrate)
    assert not info["action_mask"][layout.calibrate]
    env.close()


def test_the_default_costs_are_those_documented():
    env = CpsCampaignEnv(SMOKE)
    assert (env.cost_per_m, env.cost_per_s) == (COST_PER_M, COST_PER_S) == (0.5, 1e-3)
    assert 3600 * env.cost_per_s == pytest.approx(3.6), "an hour costs 3.6 mm"


@settings(max_examples=6, deadline=None)
@given(data=st.data(), seed=st.integers(0, 2**31))
def test_no_sequence_of_allowed_moves_earns_more_than_the_rewards_terms_allow(data, seed):
    # The predicted reward telescopes: an episode returns P0 - P_end - cost_per_m d -
    # cost_per_s t, with P0 the mean predicted error at the reset (the smoke room's one
    # camera is not calibrated: uncalibrated_error_mm), P_end >= 0 the one at the end, d the
    # travel and t the campaign's time from the reset. So the return is at most
    # uncalibrated_error_mm - cost_per_m d - cost_per_s t, whatever the moves; the budget
    # bounds the travel, the mask the calibrations (one a stay), and every episode ends
    # before the step limit.
    env = CpsCampaignEnv(SMOKE, planner="stands", uncalibrated_error_mm=600.0)
    layout = env.layout
    _, info = env.reset(seed=seed)
    start_time, total, calibrations, stays = info["time_s"], 0.0, 0, 1
    moved_since_calibration = True
    terminated = False
    for _ in range(MAX_EPISODE_STEPS):
        allowed = np.flatnonzero(info["action_mask"]).tolist()
        action = data.draw(st.sampled_from(allowed))
        travelled = info["distance_m"]
        _, reward, terminated, _, info = env.step(action)
        assert "fallback" not in info
        if action == layout.calibrate:
            assert moved_since_calibration, "a calibration repeated without moving"
            calibrations += 1
            moved_since_calibration = False
        elif info["distance_m"] > travelled:
            moved_since_calibration = True
            stays += action < layout.legs and info["decision"] == "visit"
        total += reward
        if terminated:
            break
    assert terminated, "the budget ends every episode before the step limit"
    assert calibrations <= stays
    costs = env.cost_per_m * info["distance_m"] + env.cost_per_s * (info["time_s"] - start_time)
    predicted_end = env.episode.mean_predicted_mm()
    assert total == pytest.approx(600.0 - predicted_end - costs, abs=1e-6)
    assert total <= 600.0 - costs + 1e-9
    env.close()
