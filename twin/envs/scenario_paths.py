"""Where a scenario path given to an environment is found: not only from the working
folder, so that an environment made from another folder (a training script's, a
subprocess worker's) finds the same file.

A relative path is tried, in order, against the working folder, the folder of the
environment's own scenario file (for a reset's ``options["scenario"]``: a site next to it),
and the project's ``scenarios/`` folder (:data:`PACKAGE_SCENARIOS`), as written and, for a
bare name, with ``.toml`` added (``"paper_hall"``). An absolute path is taken as it is.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["PACKAGE_ROOT", "PACKAGE_SCENARIOS", "resolve_scenario_path", "scenario_folders"]

PACKAGE_ROOT = Path(__file__).resolve().parents[2]
"""The project's folder (the one that holds the ``twin`` package)."""

PACKAGE_SCENARIOS = PACKAGE_ROOT / "scenarios"
"""The project's scenarios (``paper_hall.toml``, ``corridor.toml``...)."""


def scenario_folders(near: str | Path | None = None) -> list[Path]:
    """The folders a relative scenario path is tried against, in order: the working
    folder, the folder of ``near`` (a scenario file, when given) and
    :data:`PACKAGE_SCENARIOS` with the project's folder (for ``scenarios/NAME.toml``)."""
    folders = [Path.cwd()]
    if near:
        folders.append(Path(near).resolve().parent)
    folders += [PACKAGE_SCENARIOS, PACKAGE_ROOT]
    unique: list[Path] = []
    for folder in folders:
        if folder not in unique:
            unique.append(folder)
    return unique


def resolve_scenario_path(path: str | Path, near: str | Path | None = None) -> Path:
    """The scenario file ``path`` names (see the module); ``path`` itself where no folder
    holds it (reading it then names it as missing).

    Args:
        path: a scenario file, relative or absolute, or a bare name of the project's.
        near: the file of the scenario the path was given with (its folder is tried).
    """
    given = Path(path)
    if given.is_absolute():
        return given
    names = [given]
    if not given.suffix:
        names.append(given.with_suffix(".toml"))
    for folder in scenario_folders(near):
        for name in names:
            candidate = folder / name
            if candidate.is_file():
                return candidate
    return given
