"""Defensive reading of a campaign's results (the content of ``results.json``).

Older or partial runs may lack any field, hold ``None`` where a number is expected or
hold an empty list; these helpers turn such gaps into ``None`` or empty sequences so that
the figures and the report can say "not available" instead of failing.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.scenario.schema import Scenario

Results = Mapping[str, Any]
VisitKey = tuple[str, int]


def number(value: Any) -> float | None:
    """``value`` as a finite float, or None (missing, not a number, NaN or infinite)."""
    if isinstance(value, bool) or value is None:
        return None
    try:
        x = float(value)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def mapping(value: Any) -> Mapping[str, Any]:
    """``value`` if it is a mapping, else an empty one."""
    return value if isinstance(value, Mapping) else {}


def entries(results: Results, key: str) -> list[Mapping[str, Any]]:
    """The mappings in the list ``results[key]`` (others dropped), [] if absent."""
    value = results.get(key)
    if not isinstance(value, Sequence) or isinstance(value, str):
        return []
    return [e for e in value if isinstance(e, Mapping)]


def calibrations(results: Results) -> list[Mapping[str, Any]]:
    """The calibrations of a run, in the order they were made."""
    return entries(results, "calibrations")


def skipped_visits(results: Results) -> list[Mapping[str, Any]]:
    """The visits a run skipped, in order."""
    return entries(results, "skipped_visits")


def skipped_why(entry: Mapping[str, Any]) -> str:
    """A skipped visit's reason and message as one line, ``reason: message``."""
    reason, message = str(entry["reason"]), entry.get("message")
    return f"{reason}: {message}" if message else reason


def visit_key(entry: Mapping[str, Any]) -> VisitKey:
    """(camera, visit number) of a calibration or skipped visit; visit 0 if not given."""
    visit = number(entry.get("visit"))
    return (str(entry.get("camera", "?")), int(visit) if visit is not None else 0)


def points_xy(value: Any) -> NDArray[np.float64]:
    """A list of [x, y] (or longer) rows as an (N, 2) array; (0, 2) if unusable."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return np.zeros((0, 2))
    if arr.ndim != 2 or arr.shape[1] < 2 or arr.shape[0] == 0:
        return np.zeros((0, 2))
    arr = arr[:, :2]
    return arr[np.all(np.isfinite(arr), axis=1)]


def vector(value: Any, n: int) -> tuple[float, ...] | None:
    """A sequence of ``n`` finite numbers as a tuple, or None."""
    if not isinstance(value, Sequence) or isinstance(value, str) or len(value) != n:
        return None
    out = [number(v) for v in value]
    if any(v is None for v in out):
        return None
    return tuple(v for v in out if v is not None)


def error(entry: Mapping[str, Any], frame: str, field: str) -> float | None:
    """``entry["errors"][frame][field]`` as a number, or None (frame: world or local)."""
    return number(mapping(mapping(entry.get("errors")).get(frame)).get(field))


def planned_visits(scenario: Scenario) -> list[tuple[VisitKey, tuple[float, float]]]:
    """The scenario's visits in order: ((camera, visit number), station xy)."""
    counts: dict[str, int] = {}
    out = []
    for v in scenario.calibration.visits:
        counts[v.camera] = counts.get(v.camera, 0) + 1
        out.append(((v.camera, counts[v.camera]), (float(v.station[0]), float(v.station[1]))))
    return out


def ordinal(n: int) -> str:
    """1 -> 1st, 2 -> 2nd, 3 -> 3rd, 4 -> 4th..."""
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"


def visit_name(key: VisitKey) -> str:
    """``cam1 (1st)``: a short heading for a (camera, visit)."""
    return f"{key[0]} ({ordinal(key[1])})"
