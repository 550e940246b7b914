"""Writing variants of the scenario files for tests."""

from __future__ import annotations

from pathlib import Path

SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"


def variant(
    tmp_path: Path, name: str, replacements: list[tuple[str, str]], base: str = "smoke"
) -> Path:
    """Copy ``scenarios/<base>.toml`` to ``tmp_path/<name>.toml`` with text replaced.

    Each (old, new) pair must occur in the file, so a test cannot silently test nothing.
    """
    text = (SCENARIOS / f"{base}.toml").read_text(encoding="utf-8")
    for old, new in replacements:
        assert old in text, f"{old!r} not found in {base}.toml"
        text = text.replace(old, new, 1)
    path = tmp_path / f"{name}.toml"
    path.write_text(text, encoding="utf-8")
    return path
