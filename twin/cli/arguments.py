"""Argument types shared by the commands: each refuses a bad value with a message that
says what was expected (argparse then names the option and exits with code 2)."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from typing import Any, TypeVar

from twin.scenario.limits import MAX_SEED

Number = TypeVar("Number", int, float)

SEED_MAX = MAX_SEED
"""The largest seed accepted: the scenario's own limit (:data:`twin.scenario.limits.MAX_SEED`)."""


def _convert(text: str, kind: type, expected: str) -> Any:
    try:
        return kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None


def seed(text: str) -> int:
    """A random seed: an integer from 0 to :data:`SEED_MAX`."""
    value = _convert(text, int, "a whole number")
    if not 0 <= value <= SEED_MAX:
        raise argparse.ArgumentTypeError(f"expected 0 to 2^63 - 1, got {value}")
    return value


def positive_int(text: str) -> int:
    """A whole number of at least 1."""
    value = _convert(text, int, "a whole number")
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def int_from_1_to(most: int, what: str) -> Callable[[str], int]:
    """An argument type: a whole number from 1 to ``most`` (``what`` says why the top)."""
    return number_in(int, 1, most, why=what)


def _show(bound: float) -> str:
    return str(bound) if isinstance(bound, int) else f"{bound:g}"


def number_in(
    kind: type[Number],
    low: Number,
    high: Number | None = None,
    *,
    exclusive: bool = False,
    unit: str = "",
    why: str = "",
) -> Callable[[str], Number]:
    """An argument type: a number of ``kind`` (``int``, or ``float`` and finite) from ``low``
    to ``high`` (no top when None), both ends excluded when ``exclusive``. A value outside
    is refused with a message that gives the range, in ``unit``, and ``why`` it is so."""
    if high is None:
        expected = f"{'above' if exclusive else 'at least'} {_show(low)}"
    elif exclusive:
        expected = f"a number between {_show(low)} and {_show(high)}"
    else:
        expected = f"{_show(low)} to {_show(high)}"
    expected += f" {unit}" if unit else ""
    expected += f" ({why})" if why else ""

    def convert(text: str) -> Number:
        value = _convert(text, int, "a whole number") if kind is int else finite_float(text)
        below = value <= low if exclusive else value < low
        above = high is not None and (value >= high if exclusive else value > high)
        if below or above:
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text}")
        return value

    return convert


def positive_float(text: str) -> float:
    """A finite number above 0."""
    value = _convert(text, float, "a number")
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a finite number above 0, got {text}")
    return value


def finite_float(text: str) -> float:
    """A finite number."""
    value = _convert(text, float, "a number")
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text}")
    return value


def add_strategy(parser: argparse.ArgumentParser) -> None:
    """The ``--strategy`` option of the commands that run campaigns."""
    from twin.campaign.strategies import STRATEGIES

    parser.add_argument(
        "--strategy",
        choices=sorted(STRATEGIES),
        help="the campaign's decisions (visits, legs, data stops): planned, the paper's "
        "visits and legs with each camera's data stops chosen for accuracy; paper, the "
        "paper's own (default: the scenario's campaign.strategy, itself planned by default)",
    )


def add_overwrite(
    parser: argparse.ArgumentParser | argparse._MutuallyExclusiveGroup, file: bool = False
) -> None:
    """The ``--overwrite`` option of the commands that write a folder of results (``file``:
    a file)."""
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the file --out names (default: refuse one that exists)"
        if file
        else "replace what an earlier run wrote in --out (default: refuse a folder that is "
        "not empty)",
    )


def recorded(args: argparse.Namespace) -> dict[str, object]:
    """A command's arguments as plain values, for the manifest of its output folder."""
    out: dict[str, object] = {}
    for key, value in vars(args).items():
        if callable(value):
            continue
        if isinstance(value, list | tuple):
            out[key] = [v if isinstance(v, int | float | bool | str) else str(v) for v in value]
        else:
            plain = value is None or isinstance(value, int | float | bool | str)
            out[key] = value if plain else str(value)
    return out
