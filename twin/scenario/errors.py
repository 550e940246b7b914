"""The error raised for a bad scenario file."""

from __future__ import annotations

from collections.abc import Sized
from dataclasses import dataclass
from pathlib import Path

# Longest value an issue's message shows whole, characters; a longer one (a list of
# thousands of waypoints) is cut short.
SHOWN_CHARS = 160


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
        got = "" if self.value is None else f" (got {_shown(self.value)})"
        return f"{self.key}: {self.problem}{got}; expected {self.expected}"


def _shown(value: object) -> str:
    """``repr(value)``, cut short after ``SHOWN_CHARS`` characters."""
    text = repr(value)
    if len(text) <= SHOWN_CHARS:
        return text
    items = f", {len(value)} items" if isinstance(value, Sized) else ""
    return f"{text[:SHOWN_CHARS]}... ({len(text)} characters{items})"


class ScenarioError(ValueError):
    """A scenario file failed to parse or validate.

    Attributes:
        file: the scenario file (or ``"<dict>"`` when validated from a mapping).
        issues: every problem found, in file order where possible.
    """

    what = "scenario"
    """What kind of file it is, for the message."""

    def __init__(self, file: str | Path, issues: list[ScenarioIssue]) -> None:
        self.file = str(file)
        self.issues = list(issues)
        lines = [f"{self.file}: {len(self.issues)} problem(s) in the {self.what}:"]
        lines += [f"  - {issue}" for issue in self.issues]
        super().__init__("\n".join(lines))
