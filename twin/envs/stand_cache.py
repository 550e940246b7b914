"""The site tables of the ``stands`` planner on disk (:class:`twin.envs.stand_site.StandSite`),
so that a new process reads a site's table instead of filling it again.

One file per site, scenario digest (:func:`twin.scenario.digest.scenario_digest`), moves
(:class:`twin.envs.moves.MoveLayout`) and :data:`FORMAT`, in :func:`cache_dir`: a changed
scenario, other moves or a new format never read an old file. A file is written whole to a
temporary file and renamed over the old one, so that a reader never sees half of one; a
file that cannot be read (cut short, corrupt, another format) is ignored with a warning and
the table is built again. The files are Python pickles: the folder is the user's own.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import re
import tempfile
import warnings
from pathlib import Path
from typing import Any

from twin.envs.moves import MoveLayout
from twin.scenario.digest import scenario_digest
from twin.scenario.schema import Scenario

__all__ = ["CACHE_ENV", "FORMAT", "cache_dir", "read_table", "table_path", "write_table"]

CACHE_ENV = "TWIN_CACHE_DIR"
"""The environment variable that names the project's cache folder (the tables go in its
``stands`` folder); default ``$XDG_CACHE_HOME/camnet-twin``, else ``~/.cache/camnet-twin``."""

FORMAT = 1
"""The tables' file format: part of each file's name and checked in it."""

MAX_BYTES = 1 << 30
"""Bytes the tables' folder may hold: past it, the files least recently written are
removed (random sites each leave a table)."""


def cache_dir() -> Path:
    """The folder of the site tables (:data:`CACHE_ENV`, see there)."""
    root = os.environ.get(CACHE_ENV)
    if root:
        return Path(root).expanduser() / "stands"
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "camnet-twin" / "stands"


def _layout_digest(layout: MoveLayout) -> str:
    return hashlib.sha256(repr(layout).encode()).hexdigest()[:8]


def table_key(scenario: Scenario, layout: MoveLayout) -> dict[str, Any]:
    """What a table file records of what it was made for."""
    return {
        "format": FORMAT,
        "scenario": scenario.name,
        "scenario_digest": scenario_digest(scenario),
        "layout": repr(layout),
    }


def table_path(scenario: Scenario, layout: MoveLayout) -> Path:
    """The file of a site's table."""
    name = re.sub(r"[^A-Za-z0-9_.-]+", "_", scenario.name)[:60] or "site"
    digest = scenario_digest(scenario)
    return cache_dir() / f"{name}-{digest}-{_layout_digest(layout)}-v{FORMAT}.pkl"


def read_table(scenario: Scenario, layout: MoveLayout) -> dict[str, Any] | None:
    """The state of a site's table saved before, or None (none saved; one that cannot be
    read is named in a warning and left to be written over)."""
    path = table_path(scenario, layout)
    try:
        with path.open("rb") as f:
            saved = pickle.load(f)
    except FileNotFoundError:
        return None
    except Exception as error:  # a file cut short or corrupt: any unpickling error
        warnings.warn(
            f"{path}: the site's table cannot be read ({type(error).__name__}: {error}); "
            "it is built again",
            stacklevel=2,
        )
        return None
    if (
        not isinstance(saved, dict)
        or saved.get("key") != table_key(scenario, layout)
        or not isinstance(saved.get("state"), dict)
    ):
        warnings.warn(
            f"{path}: not this site's table (another scenario, moves or format); it is built again",
            stacklevel=2,
        )
        return None
    return saved["state"]


def write_table(scenario: Scenario, layout: MoveLayout, state: dict[str, Any]) -> Path | None:
    """Write a site's table (atomically: a temporary file renamed); None, with a warning,
    where the folder cannot be written (the table is then kept in memory only)."""
    path = table_path(scenario, layout)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
        try:
            with os.fdopen(fd, "wb") as f:
                pickle.dump(
                    {"key": table_key(scenario, layout), "state": state},
                    f,
                    protocol=pickle.HIGHEST_PROTOCOL,
                )
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        _prune(path.parent, keep=path)
    except OSError as error:
        warnings.warn(f"{path}: the site's table cannot be saved ({error})", stacklevel=2)
        return None
    return path


def _prune(folder: Path, keep: Path) -> None:
    """Remove the tables least recently written until the folder holds at most
    :data:`MAX_BYTES` (never ``keep``)."""
    files = []
    for entry in os.scandir(folder):
        if entry.name.endswith(".pkl") and entry.is_file():
            stat = entry.stat()
            files.append((stat.st_mtime, stat.st_size, Path(entry.path)))
    total = sum(size for _, size, _ in files)
    for _, size, path in sorted(files):
        if total <= MAX_BYTES:
            break
        if path != keep:
            path.unlink(missing_ok=True)
            total -= size
