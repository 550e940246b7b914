"""The marker assembly's surveying error: each child is built with its own geometry, the
campaign keeps the nominal one."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from twin.runner import built_markers
from twin.scenario import load_scenario
from twin.sim.world import build_world

SMOKE = Path(__file__).resolve().parents[3] / "scenarios" / "smoke.toml"


def _noisy(sigma: float, seed: int = 3):
    sc = load_scenario(SMOKE)
    noise = sc.noise.model_copy(update={"marker_geometry_m": sigma})
    return sc.model_copy(update={"noise": noise, "seed": seed})


def test_no_surveying_error_builds_the_nominal_assembly():
    assert built_markers(load_scenario(SMOKE)) == {}


def test_each_child_gets_its_own_error_of_the_given_size():
    sc = _noisy(0.002)
    markers = built_markers(sc)
    nominal = sc.marker.assembly()
    assert set(markers) == {c.name for c in sc.robots.children}
    errors = []
    for m in markers.values():
        errors.append(
            np.concatenate([m.cubes_body - nominal.cubes_body, m.leds_body - nominal.leds_body])
        )
    e = np.array(errors)
    # 2 children x 7 points x 3 coordinates = 42 draws: their std within 30 % of 2 mm.
    assert 0.7 * 0.002 < e.std() < 1.3 * 0.002
    assert not np.allclose(e[0], e[1])
    # The same seed draws the same error; another seed another.
    again = built_markers(_noisy(0.002))
    assert all(np.array_equal(again[k].leds_body, markers[k].leds_body) for k in markers)
    other = built_markers(_noisy(0.002, seed=4))
    assert not np.allclose(other["child1"].leds_body, markers["child1"].leds_body)


def test_the_world_is_built_with_each_childs_own_assembly():
    sc = _noisy(0.003)
    markers = built_markers(sc)
    world = build_world(sc, markers=markers)
    for name, m in markers.items():
        position, rotation = world.body_pose(name)
        cubes, leds = world.marker_points(name)
        np.testing.assert_allclose((cubes - position) @ rotation, m.cubes_body, atol=1e-9)
        np.testing.assert_allclose((leds - position) @ rotation, m.leds_body, atol=1e-9)
