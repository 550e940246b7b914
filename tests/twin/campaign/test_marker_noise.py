"""The marker assembly's surveying error: each child is built with its own geometry, the
campaign keeps the nominal one."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from twin.run.runner import built_markers
from twin.scenario import load_scenario
from twin.sim.world import build_world

SMOKE = Path(__file__).resolve().parents[3] / "scenarios" / "smoke.toml"


def _noisy(sigma: float, seed: int = 3):
    sc = load_scenario(SMOKE)
    noise = sc.noise.model_copy(update={"marker_geometry_m": sigma})
    return sc.model_copy(update={"noise": noise, "seed": seed})


def test_no_surveying_error_builds_the_nominal_assembly():
    assert built_markers(load_scenario(SMOKE)) == {}


def _errors(sc) -> np.ndarray:
    """(children, 7, 3) built minus nominal cube and LED positions, m."""
    nominal = sc.marker.assembly()
    return np.array(
        [
            np.concatenate([m.cubes_body - nominal.cubes_body, m.leds_body - nominal.leds_body])
            for m in built_markers(sc).values()
        ]
    )


# The error's size over 200 seeds: 2 children x 7 points x 3 coordinates a seed, 8400
# draws. Their mean square over sigma^2 is 1 within sqrt(2 / 8400) = 1.5 %; the band is
# 4.4 standard errors, two-sided (a false alarm once in 100 000 runs): a sigma 4 % off
# fails. Their mean is 0 within sigma / sqrt(8400), held to the same 4.4.
SEEDS = 200
K = 4.4


def test_each_child_gets_its_own_error_of_the_given_size():
    sigma = 0.002
    sc = _noisy(sigma)
    markers = built_markers(sc)
    assert set(markers) == {c.name for c in sc.robots.children}
    e = _errors(sc)
    assert not np.allclose(e[0], e[1])
    draws = np.concatenate([_errors(_noisy(sigma, seed)).ravel() for seed in range(SEEDS)])
    assert abs(np.mean(draws**2) / sigma**2 - 1) < K * np.sqrt(2 / draws.size)
    assert abs(np.mean(draws)) < K * sigma / np.sqrt(draws.size)
    # Each coordinate of each point of each child has its own draw: the 861 correlations
    # between the 42 coordinates over the seeds are 0 within 1 / sqrt(200), held to 5.3 of
    # that (1e-4 shared among them).
    corr = np.corrcoef(draws.reshape(SEEDS, -1).T)
    assert np.abs(corr[np.triu_indices_from(corr, 1)]).max() < 5.3 / np.sqrt(SEEDS)
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
