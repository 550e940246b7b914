"""Shared fixtures' helpers for the simulation tests."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import mujoco

from twin.scenario import Scenario, load_scenario

SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"


@cache
def scenario(name: str) -> Scenario:
    """A scenario file, loaded once per test session."""
    return load_scenario(SCENARIOS / f"{name}.toml")


# Object kinds that must carry a name, with the first id to check (body 0 is the world).
NAMED_KINDS = (
    (mujoco.mjtObj.mjOBJ_BODY, "nbody", 1),
    (mujoco.mjtObj.mjOBJ_SITE, "nsite", 0),
    (mujoco.mjtObj.mjOBJ_CAMERA, "ncam", 0),
    (mujoco.mjtObj.mjOBJ_GEOM, "ngeom", 0),
    (mujoco.mjtObj.mjOBJ_LIGHT, "nlight", 0),
    (mujoco.mjtObj.mjOBJ_JOINT, "njnt", 0),
    (mujoco.mjtObj.mjOBJ_ACTUATOR, "nu", 0),
)


def unnamed(model: mujoco.MjModel) -> list[str]:
    """Every body, site, camera, geom, light, joint and actuator without a name."""
    return [
        f"{kind.name} {i}"
        for kind, count, first in NAMED_KINDS
        for i in range(first, getattr(model, count))
        if not mujoco.mj_id2name(model, kind, i)
    ]
