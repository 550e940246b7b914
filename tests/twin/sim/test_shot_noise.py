"""Keyed shot noise: a shot's draw depends on what it measures, not on what came before."""

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from twin.sim.rig.shot_noise import MOVED, ShotNoise


def _draw(noise: ShotNoise, parent, child, child_xy, cube) -> float:
    return float(noise.generator(parent, child, child_xy, cube).standard_normal())


@given(extra=st.lists(st.tuples(st.integers(0, 1), st.integers(0, 2)), max_size=6))
def test_extra_shots_at_other_cubes_leave_a_shot_unchanged(extra):
    """Lost locks, re-aims and a retry at one cube do not move another cube's noise."""
    plain, busy = ShotNoise(7, 2), ShotNoise(7, 2)
    parent, kids = np.zeros(2), [np.array([3.0, 1.0]), np.array([4.0, -1.0])]
    for child, cube in extra:
        if (child, cube) != (1, 2):
            _draw(busy, parent, child, kids[child], cube)
    assert _draw(plain, parent, 1, kids[1], 2) == _draw(busy, parent, 1, kids[1], 2)


def test_a_few_centimetres_of_stop_keep_the_key_and_a_move_changes_it():
    a, b = ShotNoise(7, 2), ShotNoise(7, 2)
    parent = np.zeros(2)
    # Same place, a few centimetres apart (the fidelities' stops differ by that much).
    assert _draw(a, parent, 0, [3.0, 1.0], 0) == _draw(b, parent, 0, [3.03, 0.98], 0)
    # A second shot at the same cube and place is a repeat, with a draw of its own; the
    # same cube at the child's next place is another key again.
    repeat = _draw(a, parent, 0, [3.0, 1.0], 0)
    next_place = _draw(b, parent, 0, [3.0 + 2 * MOVED, 1.0], 0)
    assert repeat != next_place
    # Both runs' next places match, whatever the repeats before them.
    assert _draw(a, parent, 0, [3.0 + 2 * MOVED, 1.0], 0) == next_place


def test_an_extra_place_shifts_the_keys_only_until_the_parent_moves():
    one, other = ShotNoise(11, 2), ShotNoise(11, 2)
    parent = np.zeros(2)
    _draw(other, parent, 0, [9.0, 9.0], 0)  # a place only the other run measured at
    assert _draw(one, parent, 0, [3.0, 1.0], 0) != _draw(other, parent, 0, [3.0, 1.0], 0)
    later = np.array([5.0, 0.0])
    assert _draw(one, later, 0, [6.0, 1.0], 0) == _draw(other, later, 0, [6.0, 1.0], 0)


def test_seeds_give_different_noise():
    parent = np.zeros(2)
    assert _draw(ShotNoise(1, 2), parent, 0, [3.0, 1.0], 0) != _draw(
        ShotNoise(2, 2), parent, 0, [3.0, 1.0], 0
    )
