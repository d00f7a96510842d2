"""A full disk: one clear message and exit 130, nothing finished lost, no half-written file left.

Every file of a session is written under a temporary name and renamed when complete (units, the archive,
the report, session.json), so a write that fails for lack of space leaves the previous complete file (or
none) behind. The writers turn the failure into `DiskFull`; the runner parks the joint, and the session
continues with `run-protocol --resume` once space is freed (docs/session.md).
"""

from __future__ import annotations

import contextlib
import errno
import functools
import logging
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import ParamSpec, TypeVar

from ..errors import EXIT_INTERRUPTED, InvalidInput, UserError, causes

_FULL = (errno.ENOSPC, errno.EDQUOT)
P = ParamSpec("P")
R = TypeVar("R")


class DiskFull(UserError):
    """No space left while writing: nothing completed is lost; free space and --resume (exit 130)."""

    exit_code = EXIT_INTERRUPTED


def is_disk_full(exc: BaseException) -> bool:
    """Whether `exc` is (or was caused by) a write refused for lack of space or quota."""
    return any(
        isinstance(e, DiskFull)
        or (isinstance(e, OSError) and (e.errno in _FULL or "No space left on device" in str(e)))
        or (isinstance(e, RuntimeError) and _hdf5_out_of_space(str(e)))
        for e in causes(exc)
    )


def _hdf5_out_of_space(message: str) -> bool:
    """HDF5 reports a write refused for lack of space from some calls (closing a file, flushing its
    metadata) as a RuntimeError that carries the system's error in its text ("errno = 28, error message =
    'No space left on device'"), not as an OSError."""
    return (
        "No space left on device" in message
        or "Disk quota exceeded" in message
        or any(f"errno = {code}," in message for code in _FULL)
    )


def resume_hint(session_dir: Path) -> str:
    return (
        "Every step finished before it is kept. Free some space, then continue with: "
        f"run-protocol --resume {session_dir}"
    )


def disk_full_error(exc: BaseException, session_dir: Path) -> DiskFull:
    """The `DiskFull` to raise for `exc`, a write of the session refused for lack of space."""
    filename = getattr(exc, "filename", None)
    where = f" while writing {filename}" if filename else ""
    return DiskFull(f"disk full{where}. {resume_hint(session_dir)}")


def creates_session_directory(create: Callable[P, R]) -> Callable[P, R]:
    """Decorate `create_session(directory, ...)`: if it fails writing (a full disk, no permission), remove
    what it wrote, so that no half-made session is left behind, and raise one clear error."""

    @functools.wraps(create)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        directory = Path(args[0])  # type: ignore[arg-type]
        existed = directory.exists()
        try:
            was_empty = not existed or (directory.is_dir() and not any(directory.iterdir()))
        except OSError:
            was_empty = False
        try:
            return create(*args, **kwargs)
        except OSError as exc:
            if was_empty:  # only what this call wrote is removed
                with contextlib.suppress(OSError):
                    _remove_contents(directory, keep=existed)
            if is_disk_full(exc):
                raise DiskFull(
                    f"disk full while creating the session {directory}: nothing was recorded. "
                    "Free some space, then run the same command again."
                ) from None
            what = (
                f"{exc.strerror}: {exc.filename}" if exc.strerror and exc.filename else (exc.strerror or exc)
            )
            raise InvalidInput(f"--session {directory}: cannot create the session ({what})") from None

    return wrapper


def _remove_contents(directory: Path, *, keep: bool) -> None:
    if not keep:
        shutil.rmtree(directory)
        return
    for child in directory.iterdir():
        if child.is_dir() and not child.is_symlink():
            shutil.rmtree(child)
        else:
            child.unlink()


class QuietFileHandler(logging.FileHandler):
    """The session log: a line that cannot be written (full disk) is dropped without printing a
    traceback for each; the session's journal and the final message say what happened."""

    def handleError(self, record: logging.LogRecord) -> None:
        return None

    def close(self) -> None:
        try:
            super().close()
        except OSError:
            return None  # the last lines could not be flushed to a full disk
