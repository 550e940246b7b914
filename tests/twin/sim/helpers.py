"""Shared fixtures' helpers for the simulation tests."""

from __future__ import annotations

from functools import cache
from pathlib import Path

from twin.scenario import Scenario, load_scenario

SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"


@cache
def scenario(name: str) -> Scenario:
    """A scenario file, loaded once per test session."""
    return load_scenario(SCENARIOS / f"{name}.toml")
