"""Prisms hidden by their own assembly, in batches: the batch tests give, item for item,
what the tests of one item give (and the pruned prism test what testing every point of
every line gives)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from twin.campaign.plan.clearance import body_points
from twin.campaign.plan.occlusion import (
    ARM_RADIUS,
    MAST_RADIUS,
    OWN_HOUSING,
    PRISM_RADIUS,
    prisms_hidden,
    prisms_hidden_many,
    segments_distance,
    unhidden_yaw,
)

CUBES = np.array([[0.18, 0.0, 1.4], [-0.12, 0.16, 1.4], [-0.06, -0.16, 1.4]])
FLOOR = -0.4


def _distance_to_segment(points, a, b):
    d = b - a
    t = np.clip((points - a) @ d / max(float(d @ d), 1e-12), 0.0, 1.0)
    return np.linalg.norm(points - (a + t[:, None] * d), axis=1)


def _every_point_hidden(xy, yaw, cubes_body, viewer, floor_z):
    """The prism test on every point of every line of sight (no pruning)."""
    cubes = body_points(xy, yaw, cubes_body, floor_z)[0]
    base = np.array([*np.asarray(xy, dtype=float).reshape(2), floor_z])
    mast = (base, np.array([base[0], base[1], float(cubes[:, 2].max())]))
    eye = np.asarray(viewer, dtype=float)
    hidden = np.zeros(len(cubes), dtype=bool)
    for k, target in enumerate(cubes):
        v = target - eye
        n = float(np.linalg.norm(v))
        t = np.arange(max(n - 0.6, 0.0), n - OWN_HOUSING, 0.002)
        ray = eye + np.outer(t / n, v)
        hit = _distance_to_segment(ray, *mast).min() < MAST_RADIUS
        for j, other in enumerate(cubes):
            arm_end = np.array([other[0], other[1], other[2] - 0.02])
            arm_start = np.array([base[0], base[1], other[2] - 0.02])
            hit |= _distance_to_segment(ray, arm_start, arm_end).min() < ARM_RADIUS
            hit |= j != k and np.linalg.norm(ray - other, axis=1).min() < PRISM_RADIUS
        hidden[k] = hit
    return hidden


coordinate = st.floats(-6.0, 6.0, allow_nan=False)
height = st.floats(-0.3, 1.6, allow_nan=False)
viewer = st.tuples(coordinate, coordinate, height)
heading = st.floats(-4.0, 4.0, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(x=coordinate, y=coordinate, yaw=heading, eye=viewer)
def test_prisms_hidden_is_the_test_of_every_point(x, y, yaw, eye):
    xy = np.array([x, y])
    if np.hypot(eye[0] - x, eye[1] - y) < 0.7:
        eye = (x + 0.7, y, eye[2])  # an instrument stands outside the child
    expected = _every_point_hidden(xy, yaw, CUBES, eye, FLOOR)
    assert np.array_equal(prisms_hidden(xy, yaw, CUBES, eye, FLOOR), expected)


def test_grazing_views_hide_prisms_as_every_point_says():
    # Instruments close by, at the prisms' height and below: many prisms hidden.
    rng = np.random.default_rng(5)
    hidden = 0
    for _ in range(300):
        xy, yaw = rng.uniform(-1, 1, 2), rng.uniform(-np.pi, np.pi)
        angle, dist = rng.uniform(-np.pi, np.pi), rng.uniform(0.8, 6.0)
        eye = [xy[0] + dist * np.cos(angle), xy[1] + dist * np.sin(angle), rng.uniform(0.6, 1.1)]
        expected = _every_point_hidden(xy, yaw, CUBES, eye, FLOOR)
        hidden += expected.any()
        assert np.array_equal(prisms_hidden(xy, yaw, CUBES, eye, FLOOR), expected)
    assert hidden > 30


@settings(max_examples=60, deadline=None)
@given(
    x=coordinate,
    y=coordinate,
    yaws=st.lists(heading, min_size=1, max_size=5),
    eyes=st.lists(viewer, min_size=1, max_size=3),
)
def test_prisms_hidden_many_is_prisms_hidden_for_each(x, y, yaws, eyes):
    xy = np.array([x, y])
    many = prisms_hidden_many(xy, yaws, CUBES, eyes, FLOOR)
    assert many.shape == (len(yaws), len(eyes), 3)
    for i, yaw in enumerate(yaws):
        for e, eye in enumerate(eyes):
            assert np.array_equal(many[i, e], prisms_hidden(xy, yaw, CUBES, eye, FLOOR))


def _first_unhidden(xy, yaw, eyes, max_turn_deg):
    turns = np.arange(10.0, max_turn_deg + 1e-9, 10.0)
    for step in [0.0, *np.ravel(np.column_stack([turns, -turns]))]:
        y = yaw + np.radians(step)
        if not any(_every_point_hidden(xy, y, CUBES, e, FLOOR).any() for e in eyes):
            return float(y)
    return None


@settings(max_examples=40, deadline=None)
@given(
    x=st.floats(-1.0, 1.0),
    y=st.floats(-1.0, 1.0),
    yaw=heading,
    eyes=st.lists(st.tuples(coordinate, coordinate, st.floats(0.5, 1.1)), min_size=1, max_size=2),
    max_turn=st.sampled_from([0.0, 50.0, 90.0]),
)
def test_unhidden_yaw_is_the_first_heading_without_a_hidden_prism(x, y, yaw, eyes, max_turn):
    xy = np.array([x, y])
    eyes = [e if np.hypot(e[0] - x, e[1] - y) > 0.7 else (x + 0.7, y, e[2]) for e in eyes]
    expected = _first_unhidden(xy, yaw, eyes, max_turn)
    assert unhidden_yaw(xy, yaw, CUBES, eyes, FLOOR, max_turn) == expected


def _sampled_distance(p0, p1, q0, q1, n=201):
    s = np.linspace(0.0, 1.0, n)
    a = p0 + s[:, None] * (p1 - p0)
    b = q0 + s[:, None] * (q1 - q0)
    return np.linalg.norm(a[:, None] - b[None], axis=-1).min()


point3 = st.tuples(*[st.floats(-2.0, 2.0)] * 3)


@settings(max_examples=100, deadline=None)
@given(p0=point3, p1=point3, q0=point3, q1=point3, q_is_point=st.booleans())
def test_segments_distance_is_the_least_distance_of_their_points(p0, p1, q0, q1, q_is_point):
    p0, p1, q0, q1 = (np.array(v) for v in (p0, p1, q0, q1))
    if q_is_point:
        q1 = q0
    d = float(segments_distance(p0, p1, q0, q1))
    sampled = _sampled_distance(p0, p1, q0, q1)
    # Never more than the distance of any two of their points (but for the rounding of a
    # squared distance near 0); sampling every 1/200 of their lengths finds a pair nearly
    # as close.
    assert d <= sampled + 1e-7
    span = max(np.linalg.norm(p1 - p0), np.linalg.norm(q1 - q0))
    assert d >= sampled - span / 200 - 1e-9


def test_segments_distance_in_batches_is_each_alone():
    rng = np.random.default_rng(2)
    p0, p1, q0, q1 = rng.normal(size=(4, 50, 3))
    q1[::5] = q0[::5]  # some points
    p1[1::7] = p0[1::7] + 1e-9 * rng.normal(size=3)  # nearly points
    q1[2::9] = q0[2::9] + 2.0 * (p1[2::9] - p0[2::9])  # parallel
    batch = segments_distance(p0, p1, q0, q1)
    alone = [float(segments_distance(*(v[i] for v in (p0, p1, q0, q1)))) for i in range(50)]
    assert_allclose(batch, alone, rtol=0, atol=0)
    assert_allclose(segments_distance([0, 0, 0], [1, 0, 0], [0.5, 1, -1], [0.5, 1, 1]), 1.0)
    assert_allclose(segments_distance([0, 0, 0], [1, 0, 0], [2, 1, 0], [3, 1, 0]), np.sqrt(2))
