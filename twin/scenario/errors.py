"""The error raised for a bad scenario file."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class ScenarioIssue:
    """One problem in a scenario file.

    Attributes:
        key: dotted path of the offending key, e.g. ``cameras[0].position``.
        problem: what is wrong.
        value: the offending value as written (``None`` when the key is missing).
        expected: what was expected instead.
    """

    key: str
    problem: str
    value: object
    expected: str

    def __str__(self) -> str:
        got = "" if self.value is None else f" (got {self.value!r})"
        return f"{self.key}: {self.problem}{got}; expected {self.expected}"


class ScenarioError(ValueError):
    """A scenario file failed to parse or validate.

    Attributes:
        file: the scenario file (or ``"<dict>"`` when validated from a mapping).
        issues: every problem found, in file order where possible.
    """

    def __init__(self, file: str | Path, issues: list[ScenarioIssue]) -> None:
        self.file = str(file)
        self.issues = list(issues)
        lines = [f"{self.file}: {len(self.issues)} problem(s) in the scenario:"]
        lines += [f"  - {issue}" for issue in self.issues]
        super().__init__("\n".join(lines))
