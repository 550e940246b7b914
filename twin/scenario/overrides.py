"""A scenario with some of its values changed by key: for fits and sweeps that vary a few
numbers of a scenario file and need every value checked as the file's would be."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from twin.scenario.loader import scenario_from_dict
from twin.scenario.schema import Scenario


def with_values(scenario: Scenario, values: Mapping[str, object]) -> Scenario:
    """``scenario`` with each key, dotted from the top (``noise.led_centroid_px``,
    ``campaign.child_creep_m``; an item of a list by its index or, for named items, its
    name: ``cameras.cam2.led_centroid_px``), set to its value (SI units), checked as its
    file would be (each value's range, and the cross-checks between sections).

    Raises:
        KeyError: a key the scenario does not have.
        twin.scenario.ScenarioError: a value its key does not accept, or a scenario the
            cross-checks refuse (a ValueError, naming the key).
    """
    raw = scenario.model_dump(mode="json")
    source = raw.pop("source")
    for key, value in values.items():
        node = raw
        *path, last = key.split(".")
        for part in path:
            node = _child(node, part, key)
        if not isinstance(node, dict) or last not in node:
            raise KeyError(f"no key {key} in the scenario")
        node[last] = value
    return scenario_from_dict(raw, source or "<dict>")


def _child(node: Any, part: str, key: str) -> Any:
    """The item ``part`` of a section (a key) or of a list (an index, or an item's name)."""
    if isinstance(node, dict) and part in node:
        return node[part]
    if isinstance(node, list):
        if part.isdigit() and int(part) < len(node):
            return node[int(part)]
        named = [item for item in node if isinstance(item, dict) and item.get("name") == part]
        if len(named) == 1:
            return named[0]
    raise KeyError(f"no key {key} in the scenario")
