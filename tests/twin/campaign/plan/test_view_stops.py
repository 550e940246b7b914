"""The child's stops in a camera's view, tested for all candidates at once: each candidate
is kept or dropped as it is alone."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from twin.campaign.plan.clearance import body_points
from twin.campaign.plan.view_stops import (
    farthest_first,
    leds_hidden,
    leds_in_image,
    prisms_seen,
    view_stops,
)
from twin.scenario import load_scenario
from twin.scenario.geometry import floor_view

HALL = Path(__file__).resolve().parents[4] / "scenarios" / "paper_hall.toml"
RANGE = (1.3, 2200.0)
"""The instrument's range (Table I), m."""


@pytest.fixture(scope="module")
def hall():
    return load_scenario(HALL)


def _candidates(sc, camera, seed, n=300):
    """Places in and around the camera's view of the floor, facing it roughly."""
    rng = np.random.default_rng(seed)
    ground = floor_view(camera, sc.space.floor_z, 40.0, 30)[:, :2]
    xy = ground[rng.integers(0, len(ground), n)] + rng.normal(0.0, 1.5, (n, 2))
    cam = camera.position
    yaw = np.arctan2(cam[1] - xy[:, 1], cam[0] - xy[:, 0]) + rng.normal(0.0, 0.3, n)
    floor = sc.space.floor_z
    leds = body_points(xy, yaw, np.asarray(sc.marker.leds, dtype=float), floor)
    cubes = body_points(xy, yaw, np.asarray(sc.marker.cubes, dtype=float), floor)
    return leds, cubes, ground


@pytest.mark.parametrize("name", ["cam1", "cam2", "cam3"])
def test_candidate_tests_in_a_batch_are_each_alone(hall, name):
    camera = hall.camera(name).tsai()
    leds, cubes, ground = _candidates(hall, camera, seed=int(name[-1]))
    # The parent and the anchor stand in the view, where they hide some LEDs and prisms.
    parent, anchor = ground.mean(axis=0), 0.5 * (ground.mean(axis=0) + ground[0])
    inst = np.array([parent[0], parent[1], 0.0])
    kept, pixels = leds_in_image(camera, leds)
    seen = ~leds_hidden(hall.space, camera.position, leds, parent, anchor).any(axis=1)
    reachable = prisms_seen(hall.space, RANGE, inst, cubes, anchor)
    for i in range(len(leds)):
        alone, alone_pixels = leds_in_image(camera, leds[i : i + 1])
        assert (i in kept) == (alone.size == 1)
        if alone.size:
            np.testing.assert_allclose(pixels[i], alone_pixels[0], rtol=1e-12)
        one = slice(i, i + 1)
        hidden = leds_hidden(hall.space, camera.position, leds[one], parent, anchor)
        assert seen[i] == (not hidden.any())
        assert reachable[i] == prisms_seen(hall.space, RANGE, inst, cubes[one], anchor)[0]
    # Every test both keeps and drops some of these candidates.
    assert 0 < kept.size < len(leds)
    assert 0 < seen.sum() < len(leds)
    assert 0 < reachable.sum() < len(leds)


def test_view_stops_show_their_leds_and_prisms(hall):
    camera = hall.camera("cam1").tsai()
    stops = view_stops(hall.space, hall.marker.assembly(), RANGE, camera, [0, 0], 0.0, [2, 1.5])
    assert len(stops) > 20
    w, h = camera.image_size
    for s in stops[:20]:
        leds = body_points(s.stop.xy, s.stop.yaw, hall.marker.leds, hall.space.floor_z)[0]
        np.testing.assert_allclose(camera.project(leds), s.pixels, rtol=1e-12)
        assert ((s.pixels >= 12.0) & (s.pixels <= [w - 13.0, h - 13.0])).all()


def _farthest_first_reference(feats, start):
    first = int(np.argmin(np.linalg.norm(feats - start, axis=1)))
    order = [first]
    dist = np.linalg.norm(feats - feats[first], axis=1)
    dist[first] = -1.0
    while len(order) < len(feats):
        k = int(np.argmax(dist))
        order.append(k)
        dist = np.minimum(dist, np.linalg.norm(feats - feats[k], axis=1))
        dist[order] = -1.0
    return order


@settings(max_examples=50, deadline=None)
@given(n=st.integers(1, 60), seed=st.integers(0, 2**32 - 1))
def test_farthest_first_order(n, seed):
    feats = np.random.default_rng(seed).random((n, 3))
    feats[n // 2 :: 4] = feats[0]  # ties
    start = np.array([0.5, 0.5, 0.5])
    order = farthest_first(feats, start)
    assert order == _farthest_first_reference(feats, start)
    assert sorted(order) == list(range(n))
