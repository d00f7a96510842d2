"""SIGINT/SIGTERM/SIGHUP: stop at the next safe point; a second SIGINT stops at once.

The first signal sets a flag that the runner checks between steps and the rig's loop polls during a
trial; the session then parks the joint, writes its journal and exits 130, resumable. A second SIGINT
raises KeyboardInterrupt at once (units are atomic) and, in the `run-protocol` process, ends the process
with exit 130 `EXIT_DEADLINE_S` later if it is still waiting for something (a worker, the pool's threads).

Ctrl-C on a terminal signals the whole process group: `sigint_blocked` keeps SIGINT blocked while a worker
is started, so the worker inherits the block instead of dying while it imports.

A KeyboardInterrupt raised by the handler inside a weakref callback or a `__del__` cannot propagate (Python
only prints it): while installed, the stop flag delivers it again a moment later (`_thread.interrupt_main`).
"""

from __future__ import annotations

import _thread
import contextlib
import logging
import os
import signal
import sys
import threading
from collections.abc import Iterator
from types import FrameType
from typing import Any

from .streams import say

EXIT_DEADLINE_S = 10.0
"""After a second SIGINT, the longest the `run-protocol` process takes to end (exit 130)."""

_deadline = threading.Event()  # set: a second SIGINT ends the process within EXIT_DEADLINE_S
_stopped_at_once = threading.Event()  # set by a second SIGINT


def stopped_at_once() -> bool:
    """Whether a second SIGINT stopped a session of this process at once."""
    return _stopped_at_once.is_set()


def exit_at_once_after_second_sigint() -> None:
    """Arm the deadline of a second SIGINT for this process (the command-line program; a program calling
    the library keeps its process to itself)."""
    _deadline.set()


def on_the_way_out() -> None:
    """The `run-protocol` process is ending, its exit status decided: another Ctrl-C would only kill it
    (with a traceback, or exit -2 instead of its status), so it is ignored."""
    if _deadline.is_set() and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


STOP_SIGNALS = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)
"""The signals that stop a session at its next safe point (SIGHUP: not on Windows)."""


@contextlib.contextmanager
def sigint_blocked() -> Iterator[None]:
    """Block SIGINT in this thread for the duration (one that arrives meanwhile is delivered at the end, not
    lost); processes started meanwhile inherit the block. SIGTERM stays open: the pool may need it."""
    if not hasattr(signal, "pthread_sigmask"):  # Windows: plain handlers only
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


class StopFlag:
    def __init__(self) -> None:
        self._event = threading.Event()
        self.signal_name = ""
        self._previous: dict[int, Any] = {}
        self._signalled = False
        self._previous_hook: Any = None

    def __call__(self) -> bool:
        return self._event.is_set()

    def request(self, why: str = "request") -> None:
        self.signal_name = why
        self._event.set()

    def _handler(self, signum: int, frame: FrameType | None) -> None:
        name = signal.Signals(signum).name
        self._signalled = True
        if self._event.is_set() and signum == signal.SIGINT:
            _stopped_at_once.set()
            if _deadline.is_set():
                _end_after(EXIT_DEADLINE_S)
            raise KeyboardInterrupt
        self.request(name)
        say(  # a closed terminal (SIGHUP) cannot show it: dropped, never raised from here
            f"\nrun-protocol: {name} received: stopping at the next safe point (the joint will be parked). "
            "Press Ctrl-C again to stop at once."
        )

    def _unraisable(self, unraisable: Any) -> None:
        if isinstance(unraisable.exc_value, KeyboardInterrupt) and self._event.is_set():
            redeliver = threading.Timer(0.01, _thread.interrupt_main)
            redeliver.daemon = True
            redeliver.start()
            return
        self._previous_hook(unraisable)

    def install(self) -> None:
        if threading.current_thread() is not threading.main_thread():
            return
        for sig in STOP_SIGNALS:
            if sig != signal.SIGINT and signal.getsignal(sig) == signal.SIG_IGN:
                continue  # `nohup run-protocol ...`: a closed terminal is meant not to stop it
            self._previous[sig] = signal.signal(sig, self._handler)
        self._previous_hook = sys.unraisablehook
        sys.unraisablehook = self._unraisable

    def uninstall(self) -> None:
        """Restore the previous handlers; after a stop by signal, ignore SIGINT and SIGHUP instead (the
        process is on its way out)."""
        for sig, handler in self._previous.items():
            stopping = self._signalled and sig != signal.SIGTERM
            signal.signal(sig, signal.SIG_IGN if stopping else handler)
        self._previous.clear()
        if self._previous_hook is not None:
            sys.unraisablehook = self._previous_hook
            self._previous_hook = None


def _end_after(seconds: float) -> None:
    """End the process with exit 130 `seconds` from now unless it has ended by then: the way out of a wait
    that a second Ctrl-C cannot interrupt (a worker pool's thread, a lock left held by the interrupt)."""

    def end() -> None:
        with contextlib.suppress(Exception):
            logging.shutdown()
        os._exit(130)

    timer = threading.Timer(seconds, end)
    timer.daemon = True
    timer.start()
