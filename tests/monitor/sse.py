"""A small Server-Sent Events client for the monitor tests: raw sockets, one thread per stream."""

from __future__ import annotations

import contextlib
import json
import socket
import threading
import time
import urllib.error
import urllib.request
from typing import Any


def get(url: str, *, timeout: float = 5.0, headers: dict[str, str] | None = None) -> tuple[int, bytes]:
    """(status, body) of a GET; an HTTP error status is returned, not raised."""
    request = urllib.request.Request(url, headers=headers or {})
    try:
        with urllib.request.urlopen(request, timeout=timeout) as reply:
            return reply.status, reply.read()
    except urllib.error.HTTPError as exc:
        return exc.code, exc.read()


def status(base: str) -> dict[str, Any]:
    code, body = get(base + "status")
    assert code == 200, body
    return json.loads(body)


class Stream:
    """Reads `/events` in a thread and keeps every message (decoded JSON) in order."""

    def __init__(self, host: str, port: int, path: str = "/events") -> None:
        self.messages: list[dict[str, Any]] = []
        self.header = b""
        self.closed = threading.Event()
        self._new = threading.Condition()
        self.sock = socket.create_connection((host, port), timeout=30)
        self.sock.sendall(f"GET {path} HTTP/1.1\r\nHost: {host}:{port}\r\n\r\n".encode())
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        buf = b""
        try:
            while True:
                chunk = self.sock.recv(1 << 16)
                if not chunk:
                    break
                buf += chunk
                if not self.header:
                    if b"\r\n\r\n" not in buf:
                        continue
                    self.header, buf = buf.split(b"\r\n\r\n", 1)
                while b"\n\n" in buf:
                    block, buf = buf.split(b"\n\n", 1)
                    for line in block.split(b"\n"):
                        if line.startswith(b"data: "):
                            with self._new:
                                self.messages.append(json.loads(line[6:]))
                                self._new.notify_all()
        except OSError:
            pass
        finally:
            self.closed.set()
            with self._new:
                self._new.notify_all()

    def wait_for(self, kind: str, timeout: float = 30.0) -> dict[str, Any]:
        deadline = time.monotonic() + timeout
        with self._new:
            while True:
                for msg in self.messages:
                    if msg.get("type") == kind:
                        return msg
                left = deadline - time.monotonic()
                if left <= 0 or self.closed.is_set():
                    raise AssertionError(f"no {kind!r} message; got {[m.get('type') for m in self.messages]}")
                self._new.wait(left)

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.sock.shutdown(socket.SHUT_RDWR)
        self.sock.close()
        self._thread.join(timeout=5)
