"""The scenario's fields of a log's run record: what a replay needs to find the scenario
again, from another folder, and to know it is the same one."""

from __future__ import annotations

import os
from pathlib import Path

from twin.scenario.digest import scenario_identity
from twin.scenario.schema import Scenario


def scenario_fields(scenario: Scenario) -> dict[str, str]:
    """The scenario's name and digest (:func:`twin.scenario.digest.scenario_identity`), its
    file as it was given (``scenario_file``) and that file's absolute path
    (``scenario_path``; empty for a scenario not read from a file)."""
    source = scenario.source
    path = os.path.abspath(source) if source and Path(source).is_file() else ""
    return {**scenario_identity(scenario), "scenario_file": source, "scenario_path": path}
