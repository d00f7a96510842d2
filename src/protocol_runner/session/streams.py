"""Standard output and standard error that go away never stop a campaign.

A terminal closed under a running session, a pipe whose reader ended, or a stream closed before the start
(`2>&-`) makes a write raise or leaves Python without `sys.stderr`. Every progress line is in
`session.log` too, so `say` drops a line it cannot write, and points the stream's descriptor at the null
device so that later writes (and the final flush at exit) succeed silently.
"""

from __future__ import annotations

import contextlib
import os
import sys
from typing import TextIO


def say(text: str, *, stdout: bool = False) -> None:
    """Print `text` on standard error (standard output with `stdout`) and flush; a stream that is gone
    drops the line and is silenced."""
    stream = sys.stdout if stdout else sys.stderr
    if stream is None:
        return
    try:
        try:
            print(text, file=stream, flush=True)
        except UnicodeEncodeError:  # a path with a byte that is not UTF-8: shown with U+FFFD in its place
            print(text.encode("utf-8", "surrogateescape").decode("utf-8", "replace"), file=stream, flush=True)
    except (OSError, ValueError):  # a broken pipe, a hung-up terminal (EIO), a closed file
        silence(stream)


def silence(stream: TextIO) -> None:
    """Send what is still buffered in `stream`, and everything written to it later, to the null device."""
    with contextlib.suppress(OSError, ValueError, AttributeError):
        fd = stream.fileno()
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, fd)
        finally:
            os.close(null)


def reopen_missing_standard_streams() -> None:
    """Give a process started with a standard stream closed (`2>&-`) the null device in its place, before it
    opens anything: otherwise the next file it opens (the journal, a unit) gets descriptor 2, and whatever
    writes "to standard error" (a library's warning, a worker) writes into that file."""
    for fd in (0, 1, 2):
        try:
            os.fstat(fd)
        except OSError:
            null = os.open(os.devnull, os.O_RDWR)  # the lowest free descriptor: `fd` itself
            if null != fd:
                os.dup2(null, fd)
                os.close(null)
    if sys.stdout is None:
        sys.stdout = open(1, "w", closefd=False)  # noqa: SIM115  (the process's own stream)
    if sys.stderr is None:
        sys.stderr = open(2, "w", closefd=False)  # noqa: SIM115


def flush_standard_streams() -> None:
    """Flush standard output and error; one that is gone is silenced (no "Exception ignored" at exit)."""
    for stream in (sys.stdout, sys.stderr):
        if stream is None:
            continue
        try:
            stream.flush()
        except (OSError, ValueError):
            silence(stream)
