"""Slow clients cannot starve the monitor: a request must arrive whole within a deadline however its bytes
drip, the oldest unfinished request makes way for a new connection, and the URL printed on the terminal
(with its token) keeps places of its own when the monitor is full.

Every client here is on 127.0.0.1; every wait is bounded and polled, and the drip thread stops by itself.
"""

from __future__ import annotations

import contextlib
import select
import socket
import threading
import time
from collections.abc import Callable, Iterator
from types import TracebackType

import pytest

from protocol_runner.monitor.bus import EventBus
from protocol_runner.monitor.server import (
    MAX_CONNECTIONS,
    MAX_PENDING,
    OPERATOR_CONNECTIONS,
    REQUEST_DEADLINE_S,
    MonitorAddress,
    MonitorServer,
)
from protocol_runner.monitor.service import Monitor

from .sse import Stream, get, status

GENEROUS_S = 30.0  # far beyond the 5 s deadline, so a loaded machine cannot make these tests fail
DRIP_EVERY_S = 1.0  # well inside the 5 s a single read may wait: only a whole-request deadline ends a drip


class Drips:
    """`n` connections that each send one more byte of a request that never ends, every `DRIP_EVERY_S`
    seconds, from one thread that stops by itself after `for_s` seconds. Notes which ones the server
    closed (end of stream or reset)."""

    def __init__(self, port: int, n: int, *, for_s: float = 2 * GENEROUS_S) -> None:
        self.socks = [socket.create_connection(("127.0.0.1", port), timeout=GENEROUS_S) for _ in range(n)]
        self.closed: set[int] = set()
        self.rounds = 0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._end = time.monotonic() + for_s
        self._thread = threading.Thread(target=self._drip, daemon=True)
        self._thread.start()

    def _drip(self) -> None:
        head = b"GET /status HTTP/1.0\r\nHost: 127.0.0.1\r\nX-Drip: "
        k = 0
        while not self._stop.is_set() and time.monotonic() < self._end:
            byte = head[k : k + 1] or b"a"
            for i, s in enumerate(self.socks):
                if i in self.closed:
                    continue
                try:
                    readable, _, _ = select.select([s], [], [], 0)
                    gone = bool(readable) and s.recv(65536) == b""
                    if not gone:
                        s.send(byte)
                except OSError:
                    gone = True
                if gone:
                    with self._lock:
                        self.closed.add(i)
            k += 1
            with self._lock:
                self.rounds += 1
            self._stop.wait(DRIP_EVERY_S)

    def count_closed(self) -> int:
        with self._lock:
            return len(self.closed)

    def __enter__(self) -> Drips:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self._stop.set()
        self._thread.join(timeout=10)
        for s in self.socks:
            s.close()


def poll(check: Callable[[], bool], timeout_s: float = GENEROUS_S) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if check():
            return True
        time.sleep(0.1)
    return check()


@pytest.fixture
def monitor() -> Iterator[Monitor]:
    with Monitor.open("127.0.0.1:0", say=lambda text: None) as live:
        yield live


def test_a_dripping_request_is_closed_at_its_deadline(monitor: Monitor) -> None:
    with Drips(monitor.port, 3) as drips:
        # one byte a second never lets a single read time out; the whole request's deadline ends each one
        assert poll(lambda: drips.count_closed() == 3), f"{3 - drips.count_closed()} drips still open"
        assert drips.rounds >= 3  # they were dripping, not silent, when they were closed


def test_a_crowd_of_drips_does_not_starve_a_normal_request(monitor: Monitor) -> None:
    url = f"http://127.0.0.1:{monitor.port}/status"
    with Drips(monitor.port, MAX_CONNECTIONS + 4) as drips:
        assert poll(lambda: drips.rounds >= 2)  # every drip is connected and sending
        served: list[int] = []
        assert poll(lambda: served.append(get(url, timeout=GENEROUS_S)[0]) or served[-1] == 200), served
        assert poll(lambda: drips.count_closed() == len(drips.socks))  # and every drip ends by itself
    counts = status(f"http://127.0.0.1:{monitor.port}/")["monitor"]
    assert counts["dropped_requests"] >= len(drips.socks) and counts["pending_requests"] == 0
    assert (counts["max_pending_requests"], counts["request_deadline_s"]) == (MAX_PENDING, REQUEST_DEADLINE_S)


def test_the_terminal_url_keeps_a_place_when_the_monitor_is_full(monitor: Monitor) -> None:
    assert monitor.token is not None and f"?token={monitor.token}" in monitor.url
    streams = [Stream("127.0.0.1", monitor.port) for _ in range(MAX_CONNECTIONS)]
    try:
        for s in streams:
            s.wait_for("hello")
        with Drips(monitor.port, MAX_CONNECTIONS + 4) as drips:
            assert poll(lambda: drips.rounds >= 2)
            code, body = get(f"http://127.0.0.1:{monitor.port}/status")
            assert code == 503 and b"too many connections" in body  # without the token: full
            page = Stream("127.0.0.1", monitor.port, f"/events?token={monitor.token}")
            try:
                assert page.wait_for("hello")  # the operator's page still gets its stream
                code, _ = get(f"http://127.0.0.1:{monitor.port}/status?token={monitor.token}")
                assert code == 200  # and a second place: a reloaded page, or a script's /status
                assert OPERATOR_CONNECTIONS == 2
            finally:
                page.close()
    finally:
        for s in streams:
            s.close()


def test_on_a_network_bind_the_token_holder_gets_through_a_crowd_of_drips() -> None:
    # a bind that needs the token, but served on 127.0.0.1 so that nothing here is reachable from outside
    address = MonitorAddress(host="127.0.0.1", port=0, family=socket.AF_INET, loopback=False)
    bus = EventBus()
    server = MonitorServer(address, bus, token="the-token-printed-on-the-terminal")
    bus.start()
    server.start()
    url = f"http://127.0.0.1:{server.port}/status"
    try:
        with Drips(server.port, MAX_PENDING + 4) as drips:
            assert poll(lambda: drips.rounds >= 2)
            assert get(url)[0] == 403  # constant-time token check, as before
            assert get(url + "?token=the-token-printed-on-the-terminal")[0] == 200
    finally:
        bus.close()
        server.close()


def test_a_stream_opened_with_the_token_needs_no_token_elsewhere_on_loopback(monitor: Monitor) -> None:
    # on loopback the token only buys a kept place: watching without it still works
    assert get(f"http://127.0.0.1:{monitor.port}/status")[0] == 200
    assert get(f"http://127.0.0.1:{monitor.port}/status?token=wrong")[0] == 200
    with contextlib.closing(Stream("127.0.0.1", monitor.port)) as s:
        assert s.wait_for("hello")


def test_a_new_connection_closes_the_oldest_unfinished_request_first() -> None:
    address = MonitorAddress(host="127.0.0.1", port=0, family=socket.AF_INET, loopback=True)
    bus = EventBus()
    server = MonitorServer(address, bus, token=None, max_pending=2, request_deadline_s=10 * GENEROUS_S)
    bus.start()
    server.start()
    try:
        with Drips(server.port, 1) as first:
            assert poll(lambda: server.counts()["pending_requests"] == 1)
            with Drips(server.port, 1) as second:
                assert poll(lambda: server.counts()["pending_requests"] == 2)
                code, _ = get(f"http://127.0.0.1:{server.port}/status", timeout=GENEROUS_S)
                assert code == 200  # it pushed out the oldest: the first drip, not the second
                assert poll(lambda: first.count_closed() == 1)
                assert second.count_closed() == 0 and server.counts()["pending_requests"] == 1
    finally:
        bus.close()
        server.close()
