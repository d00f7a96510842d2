"""SIGINT/SIGTERM: stop at the next safe point; a second SIGINT stops at once.

The first signal sets a flag that the runner checks between steps and the rig's loop polls during a
trial (~every 100 ms); the session then parks the joint, writes its journal and exits 130, resumable.
A second SIGINT raises KeyboardInterrupt immediately: only complete units stay behind (units are atomic).

Ctrl-C on a terminal signals the whole process group, worker processes included: `sigint_blocked` keeps
SIGINT blocked while a worker is started, so the worker inherits the block (and then ignores SIGINT) instead
of dying with a traceback while it is still importing; the parent receives the signal once unblocked.

A Python signal handler runs between any two bytecodes of the main thread, also inside a weakref callback
or a `__del__`, where an exception cannot propagate: Python prints "Exception ignored in ..." with a
traceback and drops it. While installed, the stop flag catches such a dropped KeyboardInterrupt and
delivers it again a moment later (`_thread.interrupt_main`), where it can unwind the session.
"""

from __future__ import annotations

import _thread
import contextlib
import signal
import sys
import threading
from collections.abc import Iterator
from types import FrameType
from typing import Any


@contextlib.contextmanager
def sigint_blocked() -> Iterator[None]:
    """Block SIGINT in this thread for the duration (one that arrives meanwhile is delivered at the end, not
    lost); processes started meanwhile inherit the block. SIGTERM stays open: the pool may need it."""
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
            raise KeyboardInterrupt
        self.request(name)
        print(
            f"\nrun-protocol: {name} received: stopping at the next safe point (the joint will be parked). "
            "Press Ctrl-C again to stop at once.",
            file=sys.stderr,
            flush=True,
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
        for sig in (signal.SIGINT, signal.SIGTERM):
            self._previous[sig] = signal.signal(sig, self._handler)
        self._previous_hook = sys.unraisablehook
        sys.unraisablehook = self._unraisable

    def uninstall(self) -> None:
        """Restore the previous handlers; after a stop by signal, ignore SIGINT instead: the process is on
        its way out, and another Ctrl-C during its exit would only print a traceback."""
        for sig, handler in self._previous.items():
            stopping = self._signalled and sig == signal.SIGINT
            signal.signal(sig, signal.SIG_IGN if stopping else handler)
        self._previous.clear()
        if self._previous_hook is not None:
            sys.unraisablehook = self._previous_hook
            self._previous_hook = None
