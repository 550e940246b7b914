"""The same seeds give the same results, bit for bit: the stored ``results.json`` of a few
runs (:mod:`tests.twin.campaign.regression.cases`) against the code as it is now.

Only the keys the stored results hold are compared, so that results may gain keys. Not
compared: the wall time and timings (the machine's), the scenario's file name (the
checkout's), and which of the campaign's own moves and re-aims count as failures: a child
turning to show its prisms, the parent stepping aside, a prism re-aimed or searched for are
events of the campaign, not faults. They must still happen as often as before: the stored
failures of those kinds are the new run's events of those kinds.

The stores guard against unintended change. A change meant to change numbers (see
docs/changing-numbers.md) shows in its commit that the distributions agree: a Monte Carlo
of the hall before and after at each fidelity whose numbers changed (1000 trials at the
batch fidelity, 200 at the geometric one), ``benchmarks/bench_distributions.py BEFORE
AFTER --fidelity F``, whose table gives per visit the RMS camera error before and after,
their ratio and its 95 % bootstrap interval (paired by trial seed), which must hold 1.
It then regenerates the stores this processor can (``python -m
tests.twin.campaign.regression.cases``: every case, as the main store), drops those it
cannot (the other processors' stores, recorded with their processor in ``environment``),
and puts the table in its commit body.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

from tests.twin.campaign.regression.cases import CASES, environment, run_case, stored

NOT_COMPARED = ("wall_time_s", "timings_s", "scenario_file")

PROCESSOR = {"cpu", "machine"}
"""What, when it differs from where the runs were stored, makes a difference not the
code's: the comparison is skipped with the difference named."""

MOVES = ("child_turned", "parent_stepped_aside", "prism_reaimed", "prism_search")
"""The kinds that were failures in the stored results and are events now."""


def _first_difference(old: Any, new: Any, path: str = "") -> str | None:
    """Where ``new`` differs from ``old`` (only the keys of ``old``), or None."""
    if isinstance(old, dict):
        if not isinstance(new, dict):
            return f"{path}: a mapping became {type(new).__name__}"
        for key, value in old.items():
            if key not in new:
                return f"{path}/{key}: missing"
            found = _first_difference(value, new[key], f"{path}/{key}")
            if found:
                return found
        return None
    if isinstance(old, list):
        if not isinstance(new, list) or len(new) != len(old):
            size = len(new) if isinstance(new, list) else type(new).__name__
            return f"{path}: {len(old)} entries became {size}"
        for k, (a, b) in enumerate(zip(old, new, strict=True)):
            found = _first_difference(a, b, f"{path}[{k}]")
            if found:
                return found
        return None
    if isinstance(old, float) and isinstance(new, float):
        same = old == new or (math.isnan(old) and math.isnan(new))
        return None if same else f"{path}: {old!r} became {new!r} (by {new - old:.3g})"
    return None if old == new and type(old) is type(new) else f"{path}: {old!r} became {new!r}"


def _comparable(results: dict[str, Any], moved: bool) -> dict[str, Any]:
    out = {k: v for k, v in results.items() if k not in NOT_COMPARED}
    failures = dict(results.get("failures", {}))
    if moved:
        for kind, count in results.get("events", {}).items():
            if kind in MOVES:
                failures[kind] = failures.get(kind, 0) + count
    out["failures"] = dict(sorted(failures.items()))
    return out


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_the_same_seed_gives_the_same_results(case, tmp_path):
    record = stored(case)
    results = run_case(case, tmp_path)
    old = _comparable(record["results"], moved=False)
    new = _comparable(results, moved=True)
    difference = _first_difference(old, new)
    if difference is None:
        return
    here = environment()
    changed = {k: (v, here.get(k)) for k, v in record["environment"].items() if here.get(k) != v}
    if changed.keys() & PROCESSOR:
        # Vectorised maths rounds differently on another processor, and the campaign's
        # decisions amplify the last bits: bit for bit holds only where they were stored.
        pytest.skip(
            f"{case.name}: {difference}; stored on another processor "
            f"({', '.join(f'{k} {a} -> {b}' for k, (a, b) in changed.items())}): compare on "
            "one like it, or regenerate them here (python -m "
            "tests.twin.campaign.regression.cases) to check changes on this one"
        )
    if changed:
        pytest.fail(
            f"{case.name}: {difference}. The results were stored with other versions "
            f"({', '.join(f'{k} {a} -> {b}' for k, (a, b) in changed.items())}): if the "
            "upgrade explains the change, regenerate them "
            "(python -m tests.twin.campaign.regression.cases) and say so in the commit."
        )
    pytest.fail(f"{case.name}: the code computes something else than before: {difference}")
