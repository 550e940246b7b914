"""The site tables of the ``stands`` planner on disk: read back as they were written, never
for another scenario, rebuilt when unreadable, in the folder the environment names; and
filled lazily, each part the same whatever was asked first."""

from __future__ import annotations

import dataclasses
import pickle
from pathlib import Path

import numpy as np
import pytest

import twin.sim  # noqa: F401  (headless rendering)
from twin.envs import CpsCampaignEnv
from twin.envs.moves import MoveLayout
from twin.envs.stand_cache import CACHE_ENV, FORMAT, cache_dir, read_table, table_path
from twin.envs.stand_site import StandSite
from twin.envs.stand_tables import clear_sites, site_for
from twin.scenario import load_scenario
from twin.scenario.overrides import with_values

from .test_campaign_env import rollout, same

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"
LAYOUT = MoveLayout()


@pytest.fixture
def cache(tmp_path, monkeypatch) -> Path:
    """An empty cache folder of the test's own, and no table in the process."""
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    clear_sites()
    yield tmp_path / "stands"
    clear_sites()


def equal(a, b) -> bool:
    """Whether two parts of a table are equal, arrays bit for bit."""
    if dataclasses.is_dataclass(a):
        return type(a) is type(b) and all(
            equal(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a)
        )
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(equal(a[k], b[k]) for k in a)
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(equal(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and np.array_equal(a, b)
    return a == b


def _play(seeds=range(3)):
    """The rollouts of random masked play on the smoke site, with the stands planner."""
    env = CpsCampaignEnv(SMOKE, planner="stands")
    runs = [rollout(env, seed) for seed in seeds]
    env.close()
    return runs


def test_the_variable_names_the_folder_and_the_default_is_the_users_cache(tmp_path, monkeypatch):
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "mine"))
    assert cache_dir() == tmp_path / "mine" / "stands"
    monkeypatch.delenv(CACHE_ENV)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_dir() == tmp_path / "xdg" / "camnet-twin" / "stands"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache_dir() == tmp_path / "home" / ".cache" / "camnet-twin" / "stands"


def test_a_table_read_back_plays_the_same_moves_to_the_bit_without_a_world(cache):
    built = _play()
    site = site_for(load_scenario(SMOKE), LAYOUT)
    legs = dict(site.legs)
    clear_sites()  # saved when dropped
    path = table_path(site.scenario, LAYOUT)
    assert path.parent == cache
    assert f"-v{FORMAT}." in path.name
    assert path.exists()
    assert list(cache.glob("*.tmp")) == []  # written whole, then renamed
    read = _play()
    again = site_for(load_scenario(SMOKE), LAYOUT)
    assert again is not site
    # The same episodes, observation by observation and reward by reward, from the file
    # alone: no world was loaded to find a leg or to run the paper's campaign.
    for (obs_a, rew_a, _), (obs_b, rew_b, _) in zip(built, read, strict=True):
        assert len(obs_a) == len(obs_b)
        assert all(same(a, b) for a, b in zip(obs_a, obs_b, strict=True))
        assert rew_a == rew_b
    assert again._recorder is None
    assert again._prober is None
    assert again.legs.keys() == legs.keys()
    assert equal(again.legs, legs)
    assert equal(again.state(), site.state())


def test_another_scenario_does_not_read_the_table(cache):
    scenario = load_scenario(SMOKE)
    site_for(scenario, LAYOUT)
    clear_sites()
    assert read_table(scenario, LAYOUT) is not None
    changed = with_values(
        scenario, {"campaign.formation.step": 0.9 * scenario.campaign.formation.step}
    )
    assert table_path(changed, LAYOUT) != table_path(scenario, LAYOUT)
    assert read_table(changed, LAYOUT) is None
    other = StandSite(changed, LAYOUT)
    assert other._recorder is not None  # built from the paper's run, not read
    other.close()
    # Other moves do not read it either.
    assert read_table(scenario, MoveLayout(max_stations=9)) is None


def test_a_corrupt_table_is_built_again_with_a_warning(cache):
    scenario = load_scenario(SMOKE)
    built = _play(range(1))
    clear_sites()
    path = table_path(scenario, LAYOUT)
    path.write_bytes(path.read_bytes()[:100])  # cut short
    with pytest.warns(UserWarning, match="cannot be read"):
        read = _play(range(1))
    assert all(same(a, b) for a, b in zip(built[0][0], read[0][0], strict=True))
    clear_sites()
    assert read_table(scenario, LAYOUT) is not None  # written over with a good one
    path.write_bytes(pickle.dumps({"key": "another", "state": {}}))
    with pytest.warns(UserWarning, match="not this site's table"):
        assert read_table(scenario, LAYOUT) is None


def test_a_folder_that_cannot_be_written_warns_and_plays_on(cache, tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv(CACHE_ENV, str(blocker))  # its stands folder cannot be made
    with pytest.warns(UserWarning, match="cannot be read"):
        _play(range(1))
    with pytest.warns(UserWarning, match="cannot be saved"):
        clear_sites()


def test_the_paper_run_is_answered_as_far_as_asked_and_the_same_whatever_the_order(cache):
    scenario = load_scenario(SMOKE)
    ahead = StandSite(scenario, LAYOUT)
    assert not ahead.recorded
    assert ahead.data == {}  # the start only
    names = [name for name in ahead.order if ahead.stations[name].camera is not None]
    last = ahead.station_data(names[-1])
    overhead = ahead.leg_overhead
    assert ahead.data.keys() <= {*names, "start"}
    # Another table asked in the other order gets the same data, bit for bit.
    other = StandSite(scenario, LAYOUT)
    assert other.leg_overhead == overhead
    for name in reversed(names):
        other.station_data(name)
    assert equal(other.station_data(names[-1]), last)
    assert other.data.keys() == ahead.data.keys()
    # A table saved before the run was over is read back and runs it on.
    ahead.save()
    partial = StandSite(scenario, LAYOUT)
    assert not partial.recorded
    assert partial._recorder is None
    while partial._record_more():
        pass
    assert partial.recorded
    assert partial.data.keys() >= ahead.data.keys()
    for name, data in ahead.data.items():
        assert equal(partial.data[name], data)
    for site in (ahead, other, partial):
        site.close()
    assert 0 < overhead < 2.0


def test_the_folder_keeps_at_most_its_size_the_newest_first(cache, monkeypatch):
    import os

    from twin.envs import stand_cache

    cache.mkdir(parents=True)
    for k in range(3):
        (cache / f"old{k}.pkl").write_bytes(b"x" * 1000)
        os.utime(cache / f"old{k}.pkl", (k, k))
    monkeypatch.setattr(stand_cache, "MAX_BYTES", 2500)
    scenario = load_scenario(SMOKE)
    site = StandSite(scenario, LAYOUT)
    site.close()
    path = table_path(scenario, LAYOUT)
    assert path.exists()  # the newest is kept, even alone past the size
    assert not (cache / "old0.pkl").exists()
    left = sum(p.stat().st_size for p in cache.glob("*.pkl"))
    assert left <= 2500 or sorted(cache.glob("*.pkl")) == [path]


def test_a_table_dropped_from_the_kept_ones_is_saved_and_lives_on_while_held(cache, monkeypatch):
    from twin.envs import stand_tables

    monkeypatch.setattr(stand_tables, "SITES", 1)
    scenario = load_scenario(SMOKE)
    other = with_values(
        scenario, {"campaign.formation.step": 0.9 * scenario.campaign.formation.step}
    )
    held = site_for(scenario, LAYOUT)
    site_for(other, LAYOUT)  # drops the first from the process's one
    assert table_path(scenario, LAYOUT).exists()  # saved when dropped
    assert site_for(scenario, LAYOUT) is held  # still held: not built again
