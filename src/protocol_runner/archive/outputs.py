"""Files the program writes outside a session (report and comparison pages, CSV tables, .mat files,
`--reprocess`'s new archive): only ever regular files.

Each is written under a temporary name beside it (created with O_EXCL: never through a link, removed
whatever stops the write) and renamed over its path, so a path that exists and is not a regular file (by
`os.lstat`) is refused by name (exit 2) first.
"""

from __future__ import annotations

import contextlib
import os
import signal
import stat
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from ..errors import InvalidInput

_KINDS = (
    (stat.S_ISLNK, "a symbolic link"),
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISCHR, "a device"),
    (stat.S_ISBLK, "a device"),
    (stat.S_ISFIFO, "a FIFO"),
    (stat.S_ISSOCK, "a socket"),
)


def refuse_special(path: Path, what: str) -> None:
    """Raise `InvalidInput` naming `path` (and `what` writes it) when it exists and is not a regular file."""
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return
    except OSError as exc:
        raise InvalidInput(f"{what} {path}: cannot be used ({exc.strerror or exc})") from None
    if stat.S_ISREG(mode):
        return
    kind = next((name for test, name in _KINDS if test(mode)), "not a regular file")
    raise InvalidInput(
        f"{what} {path} is {kind}, not a regular file: it is not replaced (a symbolic link is never "
        "followed). Give the path of a new or a regular file"
    )


def temporary_beside(path: Path) -> Path:
    """The temporary name `path` is written under before it is renamed (hidden, unique to this process)."""
    return path.with_name(f".{path.name}.{os.getpid()}.partial")


def create_new(tmp: Path, *, newline: str | None = None) -> IO[str]:
    """Open `tmp` for UTF-8 text as a new file (a stale one removed first; O_EXCL: never through a link),
    with the umask's permissions."""
    tmp.unlink(missing_ok=True)
    return tmp.open("x", encoding="utf-8", newline=newline)


def create_binary(tmp: Path) -> IO[bytes]:
    """`create_new` for bytes."""
    tmp.unlink(missing_ok=True)
    return tmp.open("xb")


@contextlib.contextmanager
def terminated_as_interrupt() -> Iterator[None]:
    """Within the block, SIGTERM raises KeyboardInterrupt (as Ctrl-C does) so that the `finally` and `except`
    clauses that remove temporary files run; the previous handler is restored after. Only the main thread
    can set a handler: elsewhere the block runs unchanged."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    def swallowed(unraisable: sys.UnraisableHookArgs) -> None:
        # a KeyboardInterrupt raised in a finaliser or a weakref callback is only printed: deliver the
        # SIGTERM again a moment later, so that it lands in the block's own code
        if isinstance(unraisable.exc_value, KeyboardInterrupt):
            again = threading.Timer(0.01, os.kill, (os.getpid(), signal.SIGTERM))
            again.daemon = True
            again.start()
            return
        previous_hook(unraisable)

    previous, previous_hook = signal.signal(signal.SIGTERM, interrupt), sys.unraisablehook
    sys.unraisablehook = swallowed
    try:
        yield
    finally:
        sys.unraisablehook = previous_hook
        signal.signal(signal.SIGTERM, previous)
