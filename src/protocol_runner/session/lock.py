"""One process per session directory: an exclusive, non-blocking lock held while a run writes to it; and
the refusal of session files that are symbolic links.

The lock is `filelock`'s OS lock on `<session>/.lock`, so a crash or `kill -9` releases it; the holder's
PID is in `<session>/.lock.pid`, for the refusal message. The session's own files (`SESSION_FILES`) are
never followed through a symbolic link, which would have its target written: a session whose files are
links is refused with exit 2, naming the path (the session directory itself may be a link).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

from filelock import FileLock, Timeout

from ..errors import InvalidInput

LOCK_NAME = ".lock"
PID_NAME = ".lock.pid"
SESSION_FILES = (LOCK_NAME, PID_NAME, "journal.jsonl", "session.log", "units")
"""The names in a session directory that are opened for writing or appending, or written into."""

O_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
"""Makes `os.open` refuse a symbolic link as the last component (ELOOP) where the platform has it (Linux,
macOS); 0 on Windows, where the `is_symlink` check before opening stands alone."""


def refuse_link(path: Path) -> None:
    """`InvalidInput` (exit 2) if `path` is a symbolic link (or a Windows junction)."""
    if path.is_symlink() or _is_junction(path):
        raise InvalidInput(
            f"{path} is a symbolic link; a session's files must be its own (a link could make run-protocol "
            "write elsewhere). Replace it with a regular file or folder, or remove it"
        )


def _is_junction(path: Path) -> bool:
    is_junction = getattr(os.path, "isjunction", None)  # Python 3.12+
    return bool(is_junction(path)) if is_junction is not None else False


def refuse_session_links(directory: Path) -> None:
    """Refuse a session whose lock, journal, log or units folder is a symbolic link (the directory itself
    may be one)."""
    for name in SESSION_FILES:
        refuse_link(directory / name)


def open_nofollow(path: Path, flags: int, mode: int = 0o644) -> int:
    """`os.open` that never follows a symbolic link at `path`: checked first (every platform), then opened
    with O_NOFOLLOW where the platform has it, so a link swapped in between fails to open (ELOOP) there."""
    refuse_link(path)
    try:
        return os.open(path, flags | O_NOFOLLOW, mode)
    except OSError:
        if path.is_symlink():  # swapped in after the check (ELOOP)
            refuse_link(path)
        raise


@contextlib.contextmanager
def session_lock(directory: Path) -> Iterator[None]:
    """Hold the session's lock, or raise `InvalidInput` naming the holder's PID when another process has it.
    The lock file is checked not to be a link just before filelock opens it: versions before 3.20.1 follow
    one and truncate its target (later ones open it with O_NOFOLLOW)."""
    refuse_session_links(directory)
    lock = FileLock(str(directory / LOCK_NAME))
    try:
        lock.acquire(timeout=0)
    except Timeout:
        raise InvalidInput(
            f"{directory} is in use by another run-protocol (pid {_holder(directory)}); wait for it to "
            "finish or stop it"
        ) from None
    try:
        _write_pid(directory / PID_NAME)
        yield
    finally:
        lock.release()


def _write_pid(path: Path) -> None:
    with contextlib.suppress(OSError):  # only the refusal message of another process needs it
        fd = open_nofollow(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
        try:
            os.write(fd, str(os.getpid()).encode())
        finally:
            os.close(fd)


def _holder(directory: Path) -> str:
    """The PID the lock's holder wrote, or "another process" if it cannot be read (yet)."""
    try:
        fd = open_nofollow(directory / PID_NAME, os.O_RDONLY)
    except (OSError, InvalidInput):
        return "another process"
    try:
        text = os.read(fd, 32).decode(errors="replace").strip()
    finally:
        os.close(fd)
    return text if text.isdigit() else "another process"
