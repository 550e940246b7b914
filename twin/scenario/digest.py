"""A scenario's identity for files that belong to it: its name and a content digest.

Logs, camera files and Monte-Carlo folders record these two, so that a file read back with
another scenario (another space, other cameras, a changed noise model) is refused by name
instead of giving numbers that mix two sites.
"""

from __future__ import annotations

import hashlib

from twin.scenario.schema import Scenario

DIGEST_LENGTH = 16
"""Hex digits kept of the SHA-256 (64 bits: a clash between two edited scenarios is not a
practical concern)."""


def scenario_digest(scenario: Scenario) -> str:
    """A digest of everything a scenario defines, not where it was loaded from: the same
    file moved or copied keeps its digest; any change to a value changes it."""
    text = scenario.model_dump_json(exclude={"source"})
    return hashlib.sha256(text.encode()).hexdigest()[:DIGEST_LENGTH]


def scenario_identity(scenario: Scenario) -> dict[str, str]:
    """The ``{"scenario": name, "scenario_digest": digest}`` pair a file records."""
    return {"scenario": scenario.name, "scenario_digest": scenario_digest(scenario)}
