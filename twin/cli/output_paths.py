"""Output files of a command: checked before the work, written whole or not at all.

:func:`check_output_path` rejects, before any work is done, a path that names a directory or
lies under a regular file or in a folder that cannot be written, with a message that names
the option. :class:`OutputFiles` then writes each file to a temporary sibling and renames
them all into place only when every one is complete; if any write fails, the temporary
files and the folders made for them are removed, so a failed command leaves nothing behind.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable
from pathlib import Path
from types import TracebackType

from calib.io.atomic import temporary_sibling


class OutputPathError(ValueError):
    """An output path that cannot be written; the message names the option and the path."""


def _nearest_existing(path: Path) -> Path:
    """``path``'s nearest ancestor that exists (the current folder for a relative path)."""
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    return parent


def check_output_path(path: Path, option: str) -> None:
    """Raise OutputPathError unless ``path`` can be written as a file (folders may be made).

    Args:
        path: the file to write.
        option: the command-line option that named it, for the message.
    """
    if path.is_dir():
        raise OutputPathError(f"{option} {path}: is a directory; expected the name of a file")
    folder = _nearest_existing(path)
    if not folder.is_dir():
        raise OutputPathError(
            f"{option} {path}: {folder} is a file, not a directory; expected a path whose "
            "folders are directories"
        )
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputPathError(
            f"{option} {path}: directory {folder} is not writable; expected a path in a "
            "writable directory"
        )


class OutputFiles:
    """Files written together, as a context manager: all of them, or none.

    ``stage`` writes one file to a temporary sibling; leaving the ``with`` block renames
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
            OutputPathError: naming the option and the path, if the file cannot be
                written (an OSError) or ``write`` rejects what it wrote (a ValueError).
        """
        try:
            self._make_folders(path.parent)
            tmp = temporary_sibling(path)
            self._staged.append((tmp, path, option))
            write(tmp)
        except OSError as exc:
            raise OutputPathError(
                f"{option} {path}: cannot write the file ({exc.strerror or exc})"
            ) from None
        except ValueError as exc:
            raise OutputPathError(f"{option} {path}: {exc}") from None

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
                raise OutputPathError(
                    f"{option} {path}: cannot write the file ({err.strerror})"
                ) from None
