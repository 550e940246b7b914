"""A scenario path given to the environment is found from any working folder: next to the
environment's own scenario, or among the project's scenarios."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

import twin.sim  # noqa: F401  (headless rendering)
from twin.envs import CpsCampaignEnv
from twin.envs.scenario_paths import PACKAGE_SCENARIOS, resolve_scenario_path
from twin.scenario import ScenarioError

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"


@pytest.mark.parametrize("given", ["scenarios/smoke.toml", "smoke.toml", "smoke"])
def test_the_projects_scenarios_are_found_from_another_folder(given, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert PACKAGE_SCENARIOS == ROOT / "scenarios"
    assert resolve_scenario_path(given).resolve() == SMOKE
    env = CpsCampaignEnv(given)
    assert Path(env.default_scenario.source).resolve() == SMOKE
    env.close()


def test_a_reset_scenario_is_found_next_to_the_environments_own(tmp_path, monkeypatch):
    site = tmp_path / "site"
    site.mkdir()
    shutil.copy(SMOKE, site / "a.toml")
    shutil.copy(SMOKE, site / "smoke.toml")  # the project has one of that name too
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    env = CpsCampaignEnv(site / "a.toml")
    env.reset(seed=0, options={"scenario": "smoke.toml"})
    assert Path(env.scenario.source) == site / "smoke.toml", "its own folder comes first"
    env.close()


def test_the_working_folder_comes_first(tmp_path, monkeypatch):
    shutil.copy(SMOKE, tmp_path / "smoke.toml")
    monkeypatch.chdir(tmp_path)
    assert resolve_scenario_path("smoke.toml") == tmp_path / "smoke.toml"
    assert resolve_scenario_path(SMOKE) == SMOKE, "an absolute path as it is"


def test_a_missing_scenario_is_named(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ScenarioError, match=r"nowhere\.toml"):
        CpsCampaignEnv("nowhere.toml")
    env = CpsCampaignEnv(SMOKE)
    with pytest.raises(ScenarioError, match=r"nowhere\.toml"):
        env.reset(seed=0, options={"scenario": "nowhere.toml"})
    env.close()
