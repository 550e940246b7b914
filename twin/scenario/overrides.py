"""A scenario with some of its values changed by key: for fits and sweeps that vary a few
numbers of a scenario file and need every value checked as the file's would be."""

from __future__ import annotations

from collections.abc import Mapping

from twin.scenario.schema import Scenario


def with_values(scenario: Scenario, values: Mapping[str, float]) -> Scenario:
    """``scenario`` with each key, dotted from the top (``noise.led_centroid_px``,
    ``campaign.child_creep_m``), set to its value (SI units), validated.

    Raises:
        KeyError: a key the scenario does not have.
        ValueError: a value its key does not accept.
    """
    raw = scenario.model_dump()
    for key, value in values.items():
        node = raw
        *path, last = key.split(".")
        for part in path:
            if not isinstance(node, dict) or part not in node:
                raise KeyError(f"no key {key} in the scenario")
            node = node[part]
        if not isinstance(node, dict) or last not in node:
            raise KeyError(f"no key {key} in the scenario")
        node[last] = float(value)
    return type(scenario).model_validate(raw)
