"""Output folders: one run per folder, nothing half-written.

A command that writes a folder of results (``twin run``, ``twin montecarlo``, ``twin
detect``) claims it first (:func:`claim_folder`): the folder gets a small manifest
(:data:`MANIFEST`) naming the command, its arguments and whether the run finished. A
folder that holds anything else is refused unless the user asks to ``--overwrite`` it,
and then only what the command owns is cleared (the files and folders it writes); a
``twin montecarlo --resume`` continues its own run. The claim is an OS lock
(``flock`` on :data:`LOCK` in the folder) that the claiming process holds until its run
ends: a second run into the same folder, at the same time, is refused, whatever its
options; the kernel drops the lock of a process that dies, so a killed run's folder can
be resumed or overwritten. Result files are written atomically
(:func:`write_text_atomic`: to a temporary name beside them, then renamed), so that a run
killed half-way never leaves a results file that belongs to another run's log.

Single files, and the :class:`OutputError` every problem with an output path raises, are
:mod:`twin.output_files` (re-exported here).
"""

from __future__ import annotations

import contextlib
import datetime
import fcntl
import fnmatch
import json
import os
import shutil
import threading
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from twin.output_files import (
    OutputError,
    OutputFiles,
    check_file_target,
    write_bytes_atomic,
    write_text_atomic,
)

__all__ = [
    "LOCK",
    "MANIFEST",
    "RESUMABLE",
    "ClaimedFolder",
    "OutputError",
    "OutputFiles",
    "check_file_target",
    "check_folder",
    "claim_folder",
    "read_manifest",
    "write_bytes_atomic",
    "write_text_atomic",
]

MANIFEST = "twin-output.json"
"""The manifest a command writes into the folder it claims."""

LOCK = "twin-output.lock"
"""The lock file of a claimed folder: locked (``flock``) by the process that claimed the
folder for as long as its run lasts, and removed when the run ends; it records that
process's id and command. One a killed run left behind holds no lock."""

RESUMABLE = ("montecarlo",)
"""Commands that can continue their own run in a folder (``--resume``)."""

LOCK_PATIENCE = 0.2
"""Seconds a claim keeps trying a lock that is taken, so that another command's brief
look at it (:func:`check_folder`) is not taken for a run."""


class _FolderLock:
    """The lock of one claimed folder, held by this process: an open file descriptor
    of :data:`LOCK` with an exclusive ``flock`` on it.

    Attributes:
        folder: the folder (resolved). fd: the descriptor. owner: the claim that holds it
            now (a later claim of the same folder by this process takes it over).
    """

    def __init__(self, folder: Path, fd: int) -> None:
        self.folder, self.fd = folder, fd
        self.owner: object = None

    def record(self, command: str) -> None:
        """Write this process's id and ``command`` into the lock file."""
        text = json.dumps({"pid": os.getpid(), "command": command, "since": _now()}) + "\n"
        os.ftruncate(self.fd, 0)
        os.pwrite(self.fd, text.encode("utf-8"), 0)

    def release(self) -> None:
        """Remove the lock file and drop the lock (in that order: whoever opened the file
        meanwhile finds, once it has the lock, that it is not the folder's lock file any
        more, and tries again). Twice does nothing."""
        with _HELD_LOCK:
            if _HELD.get(self.folder) is self:
                del _HELD[self.folder]
        if self.fd < 0:
            return
        with contextlib.suppress(OSError):
            os.unlink(self.folder / LOCK)
        with contextlib.suppress(OSError):
            os.close(self.fd)
        self.fd = -1


_HELD: dict[Path, _FolderLock] = {}
"""The folders this process holds, by resolved path."""
_HELD_LOCK = threading.Lock()


@dataclass(frozen=True)
class ClaimedFolder:
    """A folder a command may write into, and holds until its run ends.

    The lock is released by :meth:`finished`, by :meth:`release`, on leaving a ``with``
    block, or when the process ends, however it ends.

    Attributes:
        path: the folder. command: the command that claimed it.
        resumed: whether an earlier run of the command is continued.
    """

    path: Path
    command: str
    resumed: bool = False
    _lock: _FolderLock | None = field(default=None, compare=False, repr=False)

    def finished(self, **facts: Any) -> None:
        """Mark the run in the manifest as finished, with ``facts`` beside it, and release
        the folder."""
        manifest = read_manifest(self.path) or {}
        manifest.update(complete=True, finished=_now(), **facts)
        write_text_atomic(self.path / MANIFEST, json.dumps(manifest, indent=2) + "\n")
        self.release()

    @property
    def held(self) -> bool:
        """Whether this claim still holds the folder's lock."""
        return self._lock is not None and self._lock.owner is self and self._lock.fd >= 0

    def release(self) -> None:
        """Release the folder (its lock file is removed). Twice, or after a later claim
        of the same folder by this process took it over, does nothing."""
        lock = self._lock
        if lock is not None and lock.owner is self:
            lock.owner = None
            lock.release()

    def __enter__(self) -> ClaimedFolder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def read_manifest(folder: Path) -> dict[str, Any] | None:
    """The manifest of a folder a command claimed, or None (no manifest, or unreadable)."""
    try:
        data = json.loads((Path(folder) / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def claim_folder(
    path: Path,
    command: str,
    owns: Iterable[str],
    arguments: Mapping[str, Any] | None = None,
    *,
    overwrite: bool = False,
    resume: bool = False,
    option: str = "--out",
) -> ClaimedFolder:
    """Claim ``path`` for one run of ``command``: lock it for this process (see
    :class:`ClaimedFolder` for how long), then, unless ``resume``, clear what the command
    owns there and write the manifest.

    Args:
        path: the output folder (created if missing).
        command: the command's name (``run``, ``montecarlo``...).
        owns: the names (files and folders; shell patterns such as ``frame_*.png``) the
            command writes in it. The manifest and the lock file are the command's too.
        arguments: what defines the run, for the manifest (plain values).
        overwrite: clear what the command owns in a folder that holds something else.
        resume: continue the command's own earlier run in the folder.
        option: the command-line option the path came from, for the messages.

    Raises:
        OutputError: the path is a file or under one, cannot be written, holds something
            else and neither ``overwrite`` nor (for the command's own run) ``resume`` was
            given, or another process holds it (the message names that process). Nothing
            is written then.
    """
    folder = Path(path)
    patterns = [*owns, MANIFEST]
    check_folder(folder, command, patterns, overwrite=overwrite, resume=resume, option=option)
    created = not folder.exists()
    _make_folder(folder, option, folder)
    try:
        lock = _acquire(folder, option)
    except OutputError:
        if created:
            with contextlib.suppress(OSError):  # not empty: the holder's lock file is there
                folder.rmdir()
        raise
    claimed = ClaimedFolder(folder, command, resumed=resume, _lock=lock)
    earlier, lock.owner = lock.owner, claimed

    def give_up() -> None:
        """Release the lock, or hand it back to this process's earlier claim."""
        if earlier is None:
            claimed.release()
        else:
            lock.owner = earlier

    try:
        lock.record(command)
        # Checked again under the lock: another run may have claimed it meanwhile.
        check_folder(folder, command, patterns, overwrite=overwrite, resume=resume, option=option)
        if not resume:
            for name in _owned(folder, patterns):
                _remove(folder / name)
            record = {
                "command": command,
                "arguments": dict(arguments or {}),
                "started": _now(),
                "complete": False,
                "owns": [*patterns, LOCK],
            }
            write_text_atomic(folder / MANIFEST, json.dumps(record, indent=2, default=str) + "\n")
    except OSError as exc:
        give_up()
        if created:
            shutil.rmtree(folder, ignore_errors=True)
        raise OutputError(f"{option} {folder}: cannot be written ({exc.strerror or exc})") from exc
    except BaseException:
        give_up()
        if created:
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise
    return claimed


def _acquire(folder: Path, option: str) -> _FolderLock:
    """The lock of ``folder`` for this process (taken over from an earlier claim of this
    process that was never released).

    Raises:
        OutputError: another process holds it (named), or the lock file cannot be made.
    """
    key = folder.resolve()
    with _HELD_LOCK:
        held = _HELD.get(key)
    if held is not None:
        return held
    path = key / LOCK
    deadline = time.monotonic() + LOCK_PATIENCE
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise OutputError(
                f"{option} {folder}: cannot be locked ({exc.strerror or exc})"
            ) from exc
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _read_holder(fd)
            os.close(fd)
            if time.monotonic() < deadline:
                time.sleep(0.02)
                continue
            raise OutputError(f"{option} {folder}: {_in_use(holder)}") from None
        except OSError as exc:
            os.close(fd)
            raise OutputError(
                f"{option} {folder}: cannot be locked ({exc.strerror or exc})"
            ) from exc
        # The file may have been removed by a holder that released it after we opened it:
        # then the lock we have is on a file nobody else will open.
        try:
            current = os.stat(path)
        except FileNotFoundError:
            current = None
        mine = os.fstat(fd)
        if current is not None and (current.st_dev, current.st_ino) == (mine.st_dev, mine.st_ino):
            lock = _FolderLock(key, fd)
            with _HELD_LOCK:
                _HELD[key] = lock
            return lock
        os.close(fd)


def _read_holder(fd: int) -> dict[str, Any]:
    """What a lock file says of its holder (``pid``, ``command``); empty if unreadable."""
    try:
        data = json.loads(os.pread(fd, 4096, 0).decode("utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _in_use(holder: Mapping[str, Any]) -> str:
    """Why a folder that another process holds is refused."""
    pid = holder.get("pid", "?")
    what = f"`twin {holder['command']}` run" if holder.get("command") else "run"
    since = f" since {holder['since']}" if holder.get("since") else ""
    return (
        f"in use by another {what} (process {pid}{since}); wait until it ends, or choose "
        "another folder"
    )


def _holder(folder: Path) -> dict[str, Any] | None:
    """The process that holds ``folder`` (what its lock file says), or None when no other
    process holds it. Looks without writing anything (a lock file is opened to read)."""
    key = folder.resolve()
    with _HELD_LOCK:
        if key in _HELD:
            return None
    try:
        fd = os.open(key / LOCK, os.O_RDONLY)
    except OSError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return _read_holder(fd)
        except OSError:
            return None
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)


def check_folder(
    path: Path,
    command: str,
    owns: Iterable[str],
    *,
    overwrite: bool = False,
    resume: bool = False,
    option: str = "--out",
) -> None:
    """What :func:`claim_folder` checks, without writing anything: for a command that
    claims its folder only once its work is done, to refuse a bad one before the work.
    The claim checks again, under the folder's lock.

    Raises:
        OutputError: as :func:`claim_folder`.
    """
    folder = Path(path)
    for parent in [folder, *folder.parents]:
        if parent.exists():
            if not parent.is_dir():
                where = "is a file" if parent == folder else f"lies under the file {parent}"
                raise OutputError(f"{option} {folder}: {where}; expected a folder")
            if not os.access(parent, os.W_OK | os.X_OK):
                raise OutputError(f"{option} {folder}: {parent} cannot be written")
            break
    if not folder.is_dir():
        if resume:
            raise OutputError(f"{option} {folder}: holds no `twin {command}` run to resume")
        return
    holder = _holder(folder)
    if holder is not None:
        raise OutputError(f"{option} {folder}: {_in_use(holder)}")
    manifest = read_manifest(folder)
    present = sorted(p.name for p in folder.iterdir() if p.name != LOCK)
    if resume:
        if manifest is not None and manifest.get("command") != command:
            raise OutputError(
                f"{option} {folder}: holds a `twin {manifest.get('command')}` run, not one "
                f"of `twin {command}` to resume"
            )
        if not _owned(folder, [*owns, MANIFEST]):
            raise OutputError(f"{option} {folder}: holds no `twin {command}` run to resume")
    elif present and not overwrite:
        raise OutputError(f"{option} {folder}: {_holds(manifest, present, command)}")


def _owned(folder: Path, patterns: Iterable[str]) -> list[str]:
    """The names in ``folder`` that match the command's patterns (never the lock file,
    which its holder keeps)."""
    patterns = list(patterns)
    return sorted(
        p.name
        for p in folder.iterdir()
        if p.name != LOCK and any(fnmatch.fnmatch(p.name, q) for q in patterns)
    )


def _holds(manifest: dict[str, Any] | None, present: list[str], command: str) -> str:
    """Why a folder is refused: what it holds and how to go on."""
    if manifest is not None and "command" in manifest:
        state = "a finished" if manifest.get("complete") else "an unfinished"
        what = f"holds {state} `twin {manifest['command']}` run ({manifest.get('started', '?')})"
    else:
        shown = ", ".join(present[:5]) + (", ..." if len(present) > 5 else "")
        what = f"is not empty ({shown})"
    resume = command in RESUMABLE and manifest is not None and manifest.get("command") == command
    again = "--resume to continue it, " if resume else ""
    return (
        f"{what}; pass {again}--overwrite to replace what `twin {command}` writes there, or "
        "choose another folder"
    )


def _make_folder(folder: Path, option: str, path: Path) -> None:
    for parent in [folder, *folder.parents]:
        if parent.exists() and not parent.is_dir():
            where = "is a file" if parent == path else f"lies under the file {parent}"
            raise OutputError(f"{option} {path}: {where}; expected a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{option} {path}: cannot be created ({exc.strerror or exc})") from exc


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        path.unlink()


def _now() -> str:
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
