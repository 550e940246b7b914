"""Output files: checked before the work, written whole or not at all.

A command that writes single files checks them before its work (:func:`check_file_target`)
and writes several together, all or none (:class:`OutputFiles`); a results file is written
to a temporary name beside it and renamed (:func:`write_text_atomic`), so that a reader, or
a run killed half-way, sees the old file or the new one, never half. Every problem with an
output path is an :class:`OutputError` that names the option and the path and says what
was expected; the commands turn it into exit code 2. Output folders: :mod:`twin.outputs`.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable
from pathlib import Path
from types import TracebackType

from calib.io.atomic import atomic_file, temporary_sibling


class OutputError(ValueError):
    """An output path that cannot be used: the message names the option and the path."""


def check_file_target(path: Path, option: str) -> Path:
    """``path`` as a file to write, checked before any work and without writing anything:
    not a folder, not under a file, in a folder that can be written (or can be made).

    Raises:
        OutputError: naming ``option``, the path and what was expected.
    """
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"{option} {path}: is a folder; expected the name of a file")
    folder = _nearest_existing(path.parent)
    if not folder.is_dir():
        raise OutputError(f"{option} {path}: lies under the file {folder}; expected a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputError(f"{option} {path}: the folder {folder} cannot be written")
    return path


def _nearest_existing(path: Path) -> Path:
    """``path`` or its nearest ancestor that exists."""
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def write_text_atomic(path: Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through a temporary file in the same folder and a
    rename: a reader (or a run killed half-way) sees the old file or the new one, never
    half."""
    return write_bytes_atomic(path, text.encode("utf-8"))


def write_bytes_atomic(path: Path, data: bytes) -> Path:
    """:func:`write_text_atomic` for bytes (:func:`calib.io.atomic.atomic_file`)."""
    path = Path(path)
    with atomic_file(path) as tmp:
        tmp.write_bytes(data)
    return path


class OutputFiles:
    """Files written together, as a context manager: all of them, or none.

    :meth:`stage` writes one file to a temporary sibling; leaving the ``with`` block renames
    every staged file into place, or, if the block raised, removes the temporary files and
    the folders made for them.
    """

    def __init__(self) -> None:
        self._staged: list[tuple[Path, Path, str]] = []
        self._made: list[Path] = []

    def __enter__(self) -> OutputFiles:
        return self

    def _make_folders(self, folder: Path) -> None:
        missing = []
        while not folder.exists() and folder != folder.parent:
            missing.append(folder)
            folder = folder.parent
        for f in reversed(missing):
            f.mkdir()
            self._made.append(f)

    def stage(self, path: Path, option: str, write: Callable[[Path], None]) -> None:
        """Write ``path``'s content with ``write(temporary_path)``.

        Raises:
            OutputError: naming the option and the path, if the file cannot be written
                (an OSError) or ``write`` rejects what it wrote (a ValueError).
        """
        try:
            self._make_folders(path.parent)
            tmp = temporary_sibling(path)
            self._staged.append((tmp, path, option))
            write(tmp)
        except OSError as exc:
            raise OutputError(
                f"{option} {path}: cannot write the file ({exc.strerror or exc})"
            ) from None
        except ValueError as exc:
            raise OutputError(f"{option} {path}: {exc}") from None

    def _discard(self) -> None:
        for tmp, _, _ in self._staged:
            tmp.unlink(missing_ok=True)
        for folder in reversed(self._made):
            with contextlib.suppress(OSError):  # not empty: something else was put there
                folder.rmdir()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is not None:
            self._discard()
            return
        for tmp, path, option in self._staged:
            try:
                os.replace(tmp, path)
            except OSError as err:
                self._discard()
                raise OutputError(
                    f"{option} {path}: cannot write the file ({err.strerror})"
                ) from None
