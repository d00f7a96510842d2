"""Imported by the analysis workers' fork server only (`workers.PRELOADED`), never by the session.

A worker the server forks rebuilds its task queue's locks from the session before any code of ours runs; if
the session has just ended (stopped at once by a second Ctrl-C, or killed), those locks are gone and the
half-started worker would print a traceback onto the session's terminal, after the session's own last
word. The server's exception hook, inherited by every worker it forks, stays silent for an error raised
while the session is ending or gone (the worker exits with status 1 either way); any other error is shown.
"""

from __future__ import annotations

import os
import sys
import time
from types import TracebackType

from .scipy_docs import skip_array_api_notes

skip_array_api_notes()  # first: the modules the server preloads next import scipy (scipy_docs.py)

SESSION_PID = os.getppid()  # the server's parent: the session that started it
ENDING_WAIT_S = 2.0


def _session_alive() -> bool:
    try:
        os.kill(SESSION_PID, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _session_ending() -> bool:
    """True once the session process is gone, waiting up to ENDING_WAIT_S for it to finish exiting."""
    deadline = time.monotonic() + ENDING_WAIT_S
    while _session_alive():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True


def _hook(kind: type[BaseException], value: BaseException, tb: TracebackType | None) -> None:
    if os.getpid() != _SERVER_PID and _session_ending():
        return  # a worker that could not start because the session ended: nothing to tell
    _previous(kind, value, tb)


_SERVER_PID = os.getpid()
_previous = sys.excepthook
sys.excepthook = _hook
