"""One process per session directory: an exclusive, non-blocking lock held while a run writes to it.

Two `--resume` of the same session, or `--report DIR` assembling the archive of a session that is still
running, would otherwise write the same files. The lock dies with its process (a crash releases it).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
from collections.abc import Iterator
from pathlib import Path

from ..errors import InvalidInput

LOCK_NAME = ".lock"


@contextlib.contextmanager
def session_lock(directory: Path) -> Iterator[None]:
    path = directory / LOCK_NAME
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "another process"
            raise InvalidInput(
                f"{directory} is in use by another run-protocol (pid {holder}); wait for it to finish or stop it"
            ) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0)
        yield
    finally:
        os.close(fd)  # closing releases the lock
