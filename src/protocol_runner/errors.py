"""Exceptions that carry a user-facing message and the process exit status.

Anything raised as a `UserError` is printed by the CLI as one short paragraph, never as a traceback.
"""

from __future__ import annotations

import errno
from collections.abc import Iterator
from pathlib import Path

EXIT_OK = 0
EXIT_INVALID_INPUT = 2
EXIT_HARDWARE_UNAVAILABLE = 3
EXIT_STOPPED_BY_CHECK = 4
EXIT_INTERRUPTED = 130


class UserError(Exception):
    """An error caused by the user's input or environment, with a plain message and an exit status."""

    exit_code: int = EXIT_INVALID_INPUT

    def __init__(self, message: str, exit_code: int | None = None) -> None:
        super().__init__(message)
        self.message = message
        if exit_code is not None:
            self.exit_code = exit_code

    def __str__(self) -> str:
        return self.message


class InvalidInput(UserError):
    """A protocol file, an argument or an archive is wrong (exit 2)."""


class HardwareUnavailable(UserError):
    """The DAQ boards are absent, busy, or not permitted (exit 3)."""

    exit_code = EXIT_HARDWARE_UNAVAILABLE


class StoppedByCheck(UserError):
    """A safety envelope or calibration check stopped the session (exit 4)."""

    exit_code = EXIT_STOPPED_BY_CHECK


class WatchdogTripped(StoppedByCheck):
    """A measured signal left its watchdog limit while the joint moved (`hardware/watchdog.py`): the trial
    was braked and parked, and is not kept; `--resume` redoes it (exit 4)."""

    def __init__(
        self, *, where: str, joint: str, quantity: str, value: float, limit: str, units: str, time_s: float
    ) -> None:
        self.where, self.joint, self.quantity = where, joint, quantity
        self.value, self.limit, self.units, self.time_s = value, limit, units, time_s
        super().__init__(
            f"{where}: the watchdog stopped the motion: joint {joint}'s measured {quantity} was "
            f"{value:.4g} {units} at t = {time_s:.3f} s, allowed {limit}. The robot was braked and parked; "
            "the step is not kept: once the cause is fixed, run-protocol --resume redoes it"
        )


class Interrupted(UserError):
    """The session was interrupted by a signal; it is resumable (exit 130)."""

    exit_code = EXIT_INTERRUPTED


def causes(exc: BaseException) -> Iterator[BaseException]:
    """`exc`, then the exceptions it was raised from or while handling, each once."""
    seen: set[int] = set()
    link: BaseException | None = exc
    while link is not None and id(link) not in seen:
        seen.add(id(link))
        yield link
        link = link.__cause__ or link.__context__


def short(exc: BaseException) -> str:
    """An exception's text for a one-line message: at most 160 characters, never empty."""
    text = str(exc).strip() or type(exc).__name__
    return text if len(text) <= 160 else text[:157] + "..."


def make_output_dir(path: Path, what: str) -> None:
    """Create the output directory `path` (and its parents), or an `InvalidInput` naming `what` asked for it
    and why it cannot be created."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InvalidInput(f"{what}: cannot create {path}: {exc.strerror or exc}") from None


FILE_SYSTEM_REFUSALS = frozenset(
    {errno.EROFS, errno.EACCES, errno.EPERM, errno.EISDIR, errno.ENOTDIR, errno.ELOOP, errno.EEXIST}
)
"""What a file system answers when a path cannot be used as asked (read-only, no permission, a directory
where a file belongs or the reverse, a symbolic link loop, a file in the way): said in one line, exit 2."""


def file_system_refusal(exc: BaseException) -> str | None:
    """The one-line message of an `OSError` that is one of `FILE_SYSTEM_REFUSALS` (None for anything else),
    naming the path: both paths of a rename (`os.replace`), where the one in the way is often the second."""
    if not isinstance(exc, OSError) or exc.errno not in FILE_SYSTEM_REFUSALS:
        return None
    hint = {
        errno.EROFS: "; use a writable place (a new --output or --session, or a copy of the session)",
        errno.EACCES: "; check the permissions",
        errno.EPERM: "; check the permissions",
    }.get(exc.errno or 0, "")
    what = exc.strerror or str(exc)
    if exc.filename is not None and exc.filename2 is not None:
        return f"cannot move {exc.filename} to {exc.filename2}: {what}{hint}"
    where = exc.filename if exc.filename is not None else "a file of this command"
    return f"cannot use {where}: {what}{hint}"
