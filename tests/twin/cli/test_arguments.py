"""The shared argument types: a number in a range is taken as itself, one outside it or no
number at all is refused with a message that gives the range and the text."""

from __future__ import annotations

import argparse
import math
import re

import pytest
from hypothesis import given
from hypothesis import strategies as st

from twin.cli.arguments import int_from_1_to, number_in

INTS = st.integers(-(10**6), 10**6)
FLOATS = st.floats(-1e6, 1e6, allow_nan=False)


@given(low=INTS, span=st.integers(0, 10**6), value=INTS)
def test_a_whole_number_is_taken_exactly_within_its_closed_range(low, span, value):
    high = low + span
    convert = number_in(int, low, high, unit="px", why="the sensor")
    if low <= value <= high:
        assert convert(str(value)) == value
    else:
        with pytest.raises(argparse.ArgumentTypeError) as err:
            convert(str(value))
        assert str(err.value) == f"expected {low} to {high} px (the sensor), got {value}"


@given(low=FLOATS, span=st.floats(1e-6, 1e6), value=FLOATS, exclusive=st.booleans())
def test_a_number_is_taken_within_its_range_and_its_ends_only_when_closed(
    low, span, value, exclusive
):
    high = low + span
    convert = number_in(float, low, high, exclusive=exclusive)
    inside = low < value < high if exclusive else low <= value <= high
    text = repr(value)
    if inside:
        assert convert(text) == value
    else:
        with pytest.raises(argparse.ArgumentTypeError) as err:
            convert(text)
        assert f"{low:g}" in str(err.value)
        assert f"{high:g}" in str(err.value)
        assert str(err.value).endswith(f"got {text}")


@given(low=FLOATS, value=FLOATS)
def test_without_a_top_any_finite_number_from_the_bottom_is_taken(low, value):
    convert = number_in(float, low, unit="m^2")
    if value >= low:
        assert convert(repr(value)) == value
    else:
        message = re.escape(f"expected at least {low:g} m^2, got {value!r}")
        with pytest.raises(argparse.ArgumentTypeError, match=message):
            convert(repr(value))


@pytest.mark.parametrize("text", ["nan", "inf", "-inf", "1e400"])
def test_a_number_that_is_not_finite_is_refused_whatever_the_range(text):
    with pytest.raises(argparse.ArgumentTypeError, match="finite"):
        number_in(float, -math.inf, math.inf)(text)


@pytest.mark.parametrize(
    ("kind", "text", "expected"),
    [(int, "2.5", "a whole number"), (int, "two", "a whole number"), (float, "x", "a number")],
)
def test_text_that_is_no_number_is_named(kind, text, expected):
    with pytest.raises(argparse.ArgumentTypeError, match=f"expected {expected}, got '{text}'"):
        number_in(kind, 0, 10)(text)


def test_the_count_types_say_why_their_top_is_so():
    convert = int_from_1_to(8, "the CPUs")
    assert convert("8") == 8
    with pytest.raises(argparse.ArgumentTypeError, match=r"expected 1 to 8 \(the CPUs\), got 9"):
        convert("9")
    with pytest.raises(argparse.ArgumentTypeError, match="got 0"):
        convert("0")
