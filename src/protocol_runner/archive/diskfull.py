"""A full disk: one clear message and exit 130, nothing finished lost, no half-written file left.

Every file of a session is written under a temporary name and renamed when complete, so a write that
fails for lack of space leaves the previous complete file (or none) behind. The writers turn the failure
into `DiskFull`; the runner parks the joint, and the session continues with `--resume` (docs/session.md).
"""

from __future__ import annotations

import errno
import logging
from pathlib import Path

from ..errors import EXIT_INTERRUPTED, UserError, causes

_FULL = (errno.ENOSPC, errno.EDQUOT)


class DiskFull(UserError):
    """No space left while writing: nothing completed is lost; free space and --resume (exit 130)."""

    exit_code = EXIT_INTERRUPTED


def is_disk_full(exc: BaseException) -> bool:
    """Whether `exc` is (or was caused by) a write refused for lack of space or quota."""
    return any(
        isinstance(e, DiskFull)
        or (isinstance(e, OSError) and (e.errno in _FULL or "No space left on device" in str(e)))
        # HDF5 reports a write refused for lack of space from some calls (closing a file, flushing its
        # metadata) as a RuntimeError carrying the system's error in its text ("errno = 28, ...")
        or (isinstance(e, RuntimeError) and _hdf5_out_of_space(str(e)))
        for e in causes(exc)
    )


def _hdf5_out_of_space(message: str) -> bool:
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
