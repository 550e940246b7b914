"""Switching sequences: the two constructors, their properties, and what is not a sequence."""

from __future__ import annotations

from math import comb

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib.detection import SwitchingSequence
from calib.detection.sequence import MAX_LEDS


def test_one_at_a_time_is_dark_each_led_dark() -> None:
    seq = SwitchingSequence.one_at_a_time(4)
    assert seq.n_frames == 6
    assert seq.n_leds == 4
    assert seq.dark_frames == (0, 5)
    assert seq.code_frames == (1, 2, 3, 4)
    assert [seq.lit_frames(i) for i in range(4)] == [(1,), (2,), (3,), (4,)]
    assert seq.off_code_frames(0) == (2, 3, 4)
    assert seq.code(2) == "0010"


def test_binary_four_leds_four_code_frames_of_weight_two() -> None:
    seq = SwitchingSequence.binary(4)
    assert seq.n_frames == 6
    assert seq.dark_frames == (0, 5)
    codes = seq.codes
    assert codes.shape == (4, 4)
    np.testing.assert_array_equal(codes.sum(axis=0), 2)  # constant weight
    np.testing.assert_array_equal(codes.sum(axis=1), 2)  # every frame half lit
    assert len({seq.code(i) for i in range(4)}) == 4


def test_binary_single_led_needs_two_lit_frames() -> None:
    seq = SwitchingSequence.binary(1)
    np.testing.assert_array_equal(seq.pattern[:, 0], [False, True, True, False])
    assert len(seq.lit_frames(0)) == 2


def test_pattern_is_copied_read_only_and_compared_by_value() -> None:
    raw = np.array([[0, 0], [1, 0], [0, 1], [0, 0]])
    seq = SwitchingSequence(raw)
    raw[1, 0] = 0
    assert seq.pattern[1, 0]
    with pytest.raises(ValueError, match="read-only"):
        seq.pattern[0, 0] = True
    assert seq == SwitchingSequence.one_at_a_time(2)
    assert hash(seq) == hash(SwitchingSequence.one_at_a_time(2))
    assert seq != SwitchingSequence.binary(2)
    assert "4 frames x 2 LEDs: 00 10 01 00" in repr(seq)


@pytest.mark.parametrize(
    ("pattern", "message"),
    [
        (np.zeros(4, bool), r"2-D \(n_frames, n_leds\) array, got shape \(4,\)"),
        (np.zeros((4, 0), bool), r"at least one LED column, got shape \(4, 0\)"),
        ([[1, 0], [0, 1]], "no dark frame .* among its 2 rows"),
        ([[0, 0], [1, 0], [0, 0]], "LED 1 is never lit"),
        ([[0, 0], [1, 1], [0, 0]], "LEDs 0 and 1 have the same code 1 over the 1 code frames"),
        ([[0, 0, 0], [1, 0, 1], [0, 1, 0], [0, 0, 0]], "LEDs 0 and 2 have the same code 10"),
        ([[0, 2], [1, 0]], r"booleans \(or 0/1\), got dtype int64 with values \[0, 1, 2\]"),
        ([["a"], ["b"]], "booleans"),
    ],
)
def test_invalid_patterns(pattern, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        SwitchingSequence(np.asarray(pattern))


@pytest.mark.parametrize("n", [0, -1, 2.5, MAX_LEDS + 1, 1000])
def test_constructors_need_an_integer_from_1_to_the_most(n) -> None:
    for make in (SwitchingSequence.one_at_a_time, SwitchingSequence.binary):
        with pytest.raises(ValueError, match=f"n_leds must be an integer from 1 to {MAX_LEDS}"):
            make(n)


def test_the_most_leds_make_a_sequence_at_once() -> None:
    for make in (SwitchingSequence.one_at_a_time, SwitchingSequence.binary):
        assert make(MAX_LEDS).n_leds == MAX_LEDS


def test_led_index_is_checked() -> None:
    with pytest.raises(ValueError, match=r"LED index must be 0..3, got 4"):
        SwitchingSequence.binary(4).lit_frames(4)


@settings(max_examples=16, deadline=None)
@given(n=st.integers(1, 8))
def test_constructors_give_valid_sequences_with_distinct_codes(n: int) -> None:
    for seq in (SwitchingSequence.one_at_a_time(n), SwitchingSequence.binary(n)):
        SwitchingSequence(seq.pattern)  # passes validation again
        assert seq.n_leds == n
        assert len(seq.dark_frames) >= 2  # the noise can be estimated from the frames
        codes = {seq.code(i) for i in range(n)}
        assert len(codes) == n
    one = SwitchingSequence.one_at_a_time(n)
    assert one.n_frames == n + 2
    assert all(len(one.lit_frames(i)) == 1 for i in range(n))
    binary = SwitchingSequence.binary(n)
    if n >= 2:
        m = len(binary.code_frames)
        assert m >= 4
        assert m % 2 == 0
        assert comb(m, m // 2) >= n
        assert m == 4 or comb(m - 2, m // 2 - 1) < n
        # Constant weight m/2: no LED code is matched by one frame or by all frames.
        np.testing.assert_array_equal(binary.codes.sum(axis=0), m // 2)
    # Every LED needs at least two matching frames in the binary sequence.
    assert all(len(binary.lit_frames(i)) >= 2 for i in range(n))
