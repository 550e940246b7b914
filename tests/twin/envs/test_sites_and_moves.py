"""Random sites drawn from a seed, and the layout of the moves."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import twin.sim  # noqa: F401  (headless rendering)
from twin.envs.moves import FORMATIONS, MoveLayout, formation_settings
from twin.envs.sites import KINDS, random_site
from twin.scenario.schema import FormationSettings


@pytest.mark.parametrize("kind", KINDS)
def test_a_seed_gives_one_site_and_seeds_differ(kind):
    sites = [random_site(np.random.default_rng(seed), kind) for seed in range(6)]
    again = random_site(np.random.default_rng(0), kind)
    assert again.model_dump() == sites[0].model_dump()
    assert len({s.model_dump_json() for s in sites}) == len(sites)
    for site in sites:
        assert site.name.startswith(kind)
        assert 2 <= len(site.cameras) <= 4
        assert site.space.obstacles
        # Every camera has a station (the loader checked that it sees the camera's view).
        assert {v.camera for v in site.calibration.visits} == {c.name for c in site.cameras}


def test_either_kind_is_drawn_and_a_bad_kind_is_named():
    kinds = {random_site(np.random.default_rng(s)).name.split("_")[0] for s in range(12)}
    assert kinds == set(KINDS)
    with pytest.raises(ValueError, match="unknown site kind 'maze'"):
        random_site(np.random.default_rng(0), "maze")


def test_the_paper_policy_calibrates_on_random_sites():
    from twin.envs import CpsCampaignEnv
    from twin.envs.policies import policy_named

    env = CpsCampaignEnv("random")
    calibrated = 0
    for seed in range(4):
        obs, info = env.reset(seed=seed)
        actor = policy_named("paper")(env, seed)
        while True:
            obs, _, terminated, truncated, info = env.step(actor(obs, info))
            if terminated or truncated:
                break
        calibrated += len(info["camera_errors_mm"])
    env.close()
    assert calibrated >= 4


def test_formations_are_built_from_the_scenarios():
    base = FormationSettings()
    assert formation_settings("in_line", base) == base
    side = formation_settings("side_by_side", base)
    assert side.spacing == 0.0
    assert side.lateral >= 1.0
    assert formation_settings("staggered", base).lateral == 2 * base.lateral
    assert formation_settings("long", base).spacing == 2 * base.spacing
    with pytest.raises(ValueError, match="unknown formation 'v'"):
        formation_settings("v", base)
    with pytest.raises(ValueError, match="unknown formation"):
        MoveLayout(formations=("in_line", "v"))
    with pytest.raises(ValueError, match="step factors"):
        MoveLayout(step_factors=(0.0,))
    with pytest.raises(ValueError, match="max_stations"):
        MoveLayout(max_stations=0)


def test_every_value_has_one_name():
    layout = MoveLayout(max_stations=3)
    names = [layout.describe(a) for a in range(layout.size)]
    assert len(set(names)) == layout.size
    assert names[layout.calibrate] == "calibrate"
    assert names[layout.go_to(2)] == "go_to(2)"
    assert names[layout.end] == "end"
    assert names[layout.return_start] == "return_start"
    assert layout.leg_of(layout.leg("side_by_side", 1.4)) == ("side_by_side", 1.5)
    with pytest.raises(ValueError, match="outside"):
        layout.describe(layout.size)
    with pytest.raises(ValueError, match="not a leg"):
        layout.leg_of(layout.calibrate)
    assert set(FORMATIONS) == set(layout.formations)


@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.booleans(), min_size=MoveLayout().size, max_size=MoveLayout().size),
    st.integers(-3, MoveLayout().size + 3),
)
def test_the_fallback_is_an_allowed_move(mask, action):
    layout = MoveLayout()
    mask = np.array(mask)
    if not mask.any():
        with pytest.raises(ValueError, match="no move is allowed"):
            layout.fallback(action, mask)
        return
    taken = layout.fallback(action, mask)
    assert mask[taken]
    if 0 <= action < layout.legs and mask[: layout.legs].any():
        # A leg falls back to a leg: the same formation first when it has one allowed.
        assert taken < layout.legs
        n = len(layout.step_factors)
        if mask[(action // n) * n : (action // n + 1) * n].any():
            assert taken // n == action // n


def test_the_policy_names_are_the_policies():
    from twin.envs import POLICY_NAMES
    from twin.envs.policies import POLICIES

    assert tuple(POLICIES) == POLICY_NAMES
