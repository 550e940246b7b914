"""Random sites drawn from a seed, and the layout of the moves."""

from __future__ import annotations

from decimal import Decimal
from fractions import Fraction

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
    if not 0 <= action < layout.size:
        with pytest.raises(ValueError, match=f"action {action} is outside the action space"):
            layout.fallback(action, mask)
        return
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


SIZE = MoveLayout().size
INTEGER_TYPES = (int, np.int8, np.int16, np.int32, np.int64, np.intp)
UNSIGNED_TYPES = (np.uint8, np.uint16, np.uint32, np.uint64)


def _in_range(v: int) -> int | None:
    return v if 0 <= v < SIZE else None


# (action, the move it is, or None where it is not in the space)
ACTIONS = st.one_of(
    # Integers of every kind: in the space exactly when in range.
    st.tuples(st.integers(-2 * SIZE, 2 * SIZE), st.sampled_from(INTEGER_TYPES)).map(
        lambda vt: (vt[1](vt[0]), _in_range(vt[0]))
    ),
    st.tuples(st.integers(0, 2 * SIZE), st.sampled_from(UNSIGNED_TYPES)).map(
        lambda vt: (vt[1](vt[0]), _in_range(vt[0]))
    ),
    st.integers(-(2**70), 2**70).map(lambda v: (v, _in_range(v))),
    st.tuples(st.integers(-2 * SIZE, 2 * SIZE), st.sampled_from(INTEGER_TYPES[1:])).map(
        lambda vt: (np.array(vt[0], dtype=vt[1]), _in_range(vt[0]))
    ),
    # Never: bools, floats (whole or not), longer arrays, other types.
    st.booleans().map(lambda b: (b, None)),
    st.booleans().map(lambda b: (np.bool_(b), None)),
    st.booleans().map(lambda b: (np.array(b), None)),
    st.floats().map(lambda f: (f, None)),
    st.integers(0, SIZE - 1).map(lambda v: (float(v), None)),
    st.integers(0, SIZE - 1).map(lambda v: (np.float64(v), None)),
    st.integers(0, SIZE - 1).map(lambda v: (np.float32(v), None)),
    st.integers(0, SIZE - 1).map(lambda v: (np.array(float(v)), None)),
    st.integers(0, SIZE - 1).map(lambda v: (np.array([v]), None)),
    st.integers(0, SIZE - 1).map(lambda v: ([v], None)),
    st.integers(0, SIZE - 1).map(lambda v: (str(v), None)),
    st.integers(0, SIZE - 1).map(lambda v: (complex(v), None)),
    st.integers(0, SIZE - 1).map(lambda v: (Fraction(v), None)),
    st.integers(0, SIZE - 1).map(lambda v: (Decimal(v), None)),
    st.integers(0, SIZE - 1).map(lambda v: (np.array(v, dtype=object), None)),
    st.just((None, None)),
)


@settings(max_examples=400, deadline=None)
@given(ACTIONS)
def test_an_action_is_an_integer_of_the_space(labelled):
    action, index = labelled
    layout = MoveLayout()
    if index is not None:
        value = layout.check(action)
        assert value == index
        assert type(value) is int
        return
    with pytest.raises(ValueError, match="action space") as raised:
        layout.check(action)
    message = str(raised.value)
    assert f"action {action!r} is" in message
    assert f"the action space Discrete({SIZE})" in message
    assert f"expected an int in 0 .. {SIZE - 1}" in message
    # Every entry point that takes a move refuses it the same way.
    with pytest.raises(ValueError, match="action space"):
        layout.describe(action)
    with pytest.raises(ValueError, match="action space"):
        layout.fallback(action, np.ones(SIZE, dtype=bool))


def test_the_policy_names_are_the_policies():
    from twin.envs import POLICY_NAMES
    from twin.envs.policies import POLICIES

    assert tuple(POLICIES) == POLICY_NAMES
