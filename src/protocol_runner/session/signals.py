"""SIGINT/SIGTERM: stop at the next safe point; a second SIGINT stops at once.

The first signal sets a flag that the runner checks between steps and the rig's loop polls during a
trial (~every 100 ms); the session then parks the joint, writes its journal and exits 130, resumable.
A second SIGINT raises KeyboardInterrupt immediately: only complete units stay behind (units are atomic).
"""

from __future__ import annotations

import signal
import sys
import threading
from types import FrameType
from typing import Any


class StopFlag:
    def __init__(self) -> None:
        self._event = threading.Event()
        self.signal_name = ""
        self._previous: dict[int, Any] = {}

    def __call__(self) -> bool:
        return self._event.is_set()

    def request(self, why: str = "request") -> None:
        self.signal_name = why
        self._event.set()

    def _handler(self, signum: int, frame: FrameType | None) -> None:
        name = signal.Signals(signum).name
        if self._event.is_set() and signum == signal.SIGINT:
            raise KeyboardInterrupt
        self.request(name)
        print(
            f"\nrun-protocol: {name} received: stopping at the next safe point (the joint will be parked). "
            "Press Ctrl-C again to stop at once.",
            file=sys.stderr,
            flush=True,
        )

    def install(self) -> None:
        if threading.current_thread() is not threading.main_thread():
            return
        for sig in (signal.SIGINT, signal.SIGTERM):
            self._previous[sig] = signal.signal(sig, self._handler)

    def uninstall(self) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous.clear()
