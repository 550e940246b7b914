"""The ``stands`` planner: the campaign's moves read from a table of the site, with the
environment's guarantees (checker, determinism, pickling, masks) and the paper's campaign
where it plays the paper's moves."""

from __future__ import annotations

import itertools
import math
import pickle
import warnings
from pathlib import Path

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from hypothesis import given
from hypothesis import strategies as st

import twin.sim  # noqa: F401  (headless rendering)
from twin.batch.steps import PlanSession
from twin.envs import ENV_ID, CpsCampaignEnv
from twin.envs.stand_tables import site_for
from twin.envs.stands import STD_STEP, rounded_std
from twin.scenario import Scenario, load_scenario

from .test_campaign_env import rollout, same, without_reference

ROOT = Path(__file__).resolve().parents[3]
CORRIDOR = ROOT / "scenarios" / "corridor.toml"
SMOKE = ROOT / "scenarios" / "smoke.toml"


def _env(scenario: Path | Scenario = CORRIDOR, **kwargs) -> CpsCampaignEnv:
    return CpsCampaignEnv(scenario, planner="stands", **kwargs)


def test_check_env_passes_without_warnings():
    env = gymnasium.make(
        f"twin.envs:{ENV_ID}", scenario=SMOKE, planner="stands", render_mode="rgb_array"
    ).unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env)
    env.close()


def test_the_table_cuts_the_route_into_cells_no_longer_than_the_shortest_step():
    env = _env()
    env.reset(seed=0)
    site = env.planner.site
    layout = env.layout
    assert site.cell == pytest.approx(
        min(layout.step_factors) * site.scenario.campaign.formation.step
    )
    route = sorted(s.arc for s in site.stands if s.station is None)
    assert max(np.diff(route)) <= site.cell + 1e-9
    for name, station in site.stations.items():
        assert np.array_equal(site.at[name].xy, station.xy)  # each station is a stand
    # A travel runs along the route towards the goal and ends at its station.
    here = site.at["start"]
    for goal in site.order:
        stands, direction = site.travel(here, goal)
        assert stands[-1] is site.at[goal]
        arcs = [s.arc for s in stands]
        assert all(direction * (b - a) > 0 for a, b in itertools.pairwise(arcs))
    env.close()


def test_same_seed_same_rollout_and_reseeding_replays():
    a, b = _env(), _env()
    lengths = 0
    for seed in range(5, 9):
        first, second = rollout(a, seed), rollout(b, seed)
        assert len(first[0]) == len(second[0])
        assert all(same(x, y) for x, y in zip(first[0], second[0], strict=True))
        assert first[1] == second[1]
        lengths += len(first[0])
    assert lengths > 12
    again = rollout(a, 8)
    assert all(same(x, y) for x, y in zip(first[0], again[0], strict=True))
    a.close()
    b.close()


def test_observations_lie_in_the_space_and_masks_hold():
    env = _env()
    for seed in range(4):
        observations, _, infos = rollout(env, seed)
        assert all(env.observation_space.contains(o) for o in observations)
        assert all("fallback" not in info for info in infos[1:])
    env.close()


def test_pickling_round_trips_and_every_allowed_move_executes():
    env = _env(without_reference(CORRIDOR))  # taken before the first move, by every copy
    obs, info = env.reset(seed=2)
    rng = np.random.default_rng(2)
    decisions = set()
    for _ in range(8):
        decisions.add(info["decision"])
        for action in np.flatnonzero(info["action_mask"]):
            trial = pickle.loads(pickle.dumps(env))
            assert same(trial.episode.observation(), obs)
            _, _, _, _, after = trial.step(int(action))
            assert "fallback" not in after
            assert after["move"] == env.layout.describe(int(action))
            trial.close()
        moves = np.flatnonzero(info["action_mask"])
        moves = moves[moves != env.layout.end] if len(moves) > 1 else moves
        obs, _, terminated, _, info = env.step(int(rng.choice(moves)))
        if terminated:
            break
    assert decisions == {"leg", "visit"}
    env.close()


def test_a_forbidden_move_runs_its_fallback_and_strict_raises():
    env = _env()
    _, info = env.reset(seed=3)
    forbidden = int(np.flatnonzero(~info["action_mask"])[0])
    _, _, _, _, after = env.step(forbidden)
    assert after["fallback"]["requested"] == forbidden
    assert info["action_mask"][after["fallback"]["taken"]]
    strict = _env(strict=True)
    _, info = strict.reset(seed=3)
    with pytest.raises(ValueError, match="not allowed"):
        strict.step(int(np.flatnonzero(~info["action_mask"])[0]))
    env.close()
    strict.close()


def test_the_paper_moves_give_the_papers_campaign():
    # The paper's moves on the table and on the campaign itself: the same visits, the
    # same stations, and travel and time within a few per cent (legs on stands, not cut
    # evenly between stations).
    results, clocks = {}, {}
    for planner in ("campaign", "stands"):
        env = CpsCampaignEnv(CORRIDOR, planner=planner)
        _, _, infos = rollout(env, 9, policy="paper")
        last = infos[-1]
        results[planner] = (sorted(last["camera_errors_mm"]), last["distance_m"], last["time_s"])
        clocks[planner] = np.diff([info["time_s"] for info in infos])
        env.close()
    assert results["stands"][0] == results["campaign"][0]
    assert results["stands"][1] == pytest.approx(results["campaign"][1], rel=0.05)
    assert results["stands"][2] == pytest.approx(results["campaign"][2], rel=0.1)
    # Move by move too: each leg's drives from where the robots stood (the first from
    # where the reference data left the children) and its shots. The campaign's legs add
    # the drives that clear a child's view, about 1.4 s at most here; a leg whose drives
    # started from the wrong place would be off by one robot's drive, 15 s on this route.
    assert len(clocks["stands"]) == len(clocks["campaign"])
    np.testing.assert_allclose(clocks["stands"], clocks["campaign"], atol=2.0)


def test_the_vector_runs_the_table_as_the_single_environment():
    n = 3
    vector = gymnasium.make_vec(
        f"twin.envs:{ENV_ID}", num_envs=n, scenario=str(CORRIDOR), planner="stands"
    )
    singles = [_env() for _ in range(n)]
    obs, _ = vector.reset(seed=40)
    state = [env.reset(seed=40 + k) for k, env in enumerate(singles)]
    rng = np.random.default_rng(0)
    done = np.zeros(n, dtype=bool)
    for _ in range(25):
        actions = np.array(
            [
                0 if done[k] else rng.choice(np.flatnonzero(state[k][-1]["action_mask"]))
                for k in range(n)
            ]
        )
        obs, rewards, terminated, truncated, _ = vector.step(actions)
        for k, env in enumerate(singles):
            state[k] = env.reset() if done[k] else env.step(int(actions[k]))
            assert same({key: v[k] for key, v in obs.items()}, state[k][0])
            if not done[k]:
                assert rewards[k] == state[k][1]
        done = terminated | truncated
    vector.close()
    for env in singles:
        env.close()


def test_a_robots_truth_does_not_depend_on_the_probes_before():
    scenario = load_scenario(SMOKE)
    with PlanSession(scenario, "paper") as session:
        pose = np.array([1.5, 0.4, 0.3])
        first = session.truth_at("child1", pose)
        session.truth_at("child2", pose + np.array([0.4, 0.0, 0.0]))  # next to it
        session.truth_at("child1", pose + np.array([2.0, 1.0, 1.0]))
        again = session.truth_at("child1", pose)
    assert np.array_equal(first.leds, again.leds)
    assert np.array_equal(first.pose, again.pose)
    assert np.linalg.norm(first.pose[:2] - pose[:2]) < 1e-3


def test_the_sites_table_is_shared_within_a_process():
    a, b = _env(), _env()
    a.reset(seed=1)
    b.reset(seed=2)
    assert a.planner.site is b.planner.site is site_for(a.scenario, a.layout)
    a.close()
    b.close()


@given(st.floats(0.0, 1.0), st.floats(0.0, 1.0), st.floats(-0.9, 0.9))
def test_the_rounded_std_is_the_next_multiple_above(sx, sy, rho):
    cov = np.zeros((4, 4))
    cov[1:3, 1:3] = [[sx**2, rho * sx * sy], [rho * sx * sy, sy**2]]
    std = math.sqrt(max(np.linalg.eigvalsh(cov[1:3, 1:3]).max(), 0.0))
    rounded = rounded_std(cov)
    assert rounded >= std - 1e-9
    assert rounded - std < STD_STEP + 1e-9
    assert rounded / STD_STEP == pytest.approx(round(rounded / STD_STEP))


def test_a_lost_trial_plans_with_the_narrowest_margin():
    assert rounded_std(np.full((4, 4), np.nan)) == 0.0


def test_an_unknown_planner_is_named():
    with pytest.raises(ValueError, match="planner must be one of"):
        CpsCampaignEnv(CORRIDOR, planner="grid")
