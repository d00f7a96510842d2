"""The monitor's HTTP server (standard library only, background threads, read-only): `/`, `/events`
(Server-Sent Events), `/status`, with docs/monitor.md's address checks and limits; and its address,
`--monitor [HOST:]PORT` (default host 127.0.0.1, loopback; port 0: the system picks a free one).
"""

from __future__ import annotations

import base64
import contextlib
import hashlib
import hmac
import io
import ipaddress
import queue
import select
import socket
import socketserver
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from typing import Any
from urllib.parse import parse_qs, urlsplit

from ..errors import InvalidInput
from .bus import EventBus, dumps

DEFAULT_HOST = "127.0.0.1"

_USAGE = "give [HOST:]PORT, e.g. --monitor 8765 or --monitor 127.0.0.1:8765 (IPv6: --monitor [::1]:8765)"


@dataclass(frozen=True)
class MonitorAddress:
    host: str
    port: int
    family: socket.AddressFamily
    loopback: bool

    def url_host(self) -> str:
        """The host as a URL writes it (an unspecified address becomes this machine's name)."""
        host = self.host
        if host in ("0.0.0.0", "::", ""):
            host = socket.gethostname()
        return f"[{host}]" if ":" in host else host


def parse_address(spec: str) -> MonitorAddress:
    text = spec.strip()
    if text.startswith("["):
        host, sep, port_text = text[1:].partition("]:")
        if not sep:
            raise InvalidInput(f"--monitor {spec!r}: {_USAGE}")
    elif text.count(":") == 1:
        host, port_text = text.split(":")
    elif ":" in text:
        raise InvalidInput(f"--monitor {spec!r}: an IPv6 host goes in brackets, e.g. --monitor [::1]:8765")
    else:
        host, port_text = DEFAULT_HOST, text
    host = host.strip() or DEFAULT_HOST
    try:
        port = int(port_text)
    except ValueError:
        raise InvalidInput(f"--monitor {spec!r}: {port_text!r} is not a port number; {_USAGE}") from None
    if not 0 <= port <= 65535:
        raise InvalidInput(
            f"--monitor {spec!r}: port {port} is out of range (1-65535, or 0 for any free port)"
        )
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError):
        raise InvalidInput(f"--monitor {spec!r}: cannot resolve the host {host!r}") from None
    loopback = all(_is_loopback(str(info[4][0])) for info in infos)
    return MonitorAddress(host=host, port=port, family=infos[0][0], loopback=loopback)


def _is_loopback(address: str) -> bool:
    try:
        return ipaddress.ip_address(address.split("%", 1)[0]).is_loopback
    except ValueError:
        return False


def is_loopback_host_header(value: str) -> bool:
    """Does an HTTP Host header name this machine's loopback (localhost, 127.x.x.x, [::1])?"""
    value = value.strip()
    if value.startswith("["):
        name = value[1 : value.find("]")] if "]" in value else value[1:]
    else:
        name = value.rsplit(":", 1)[0] if value.count(":") == 1 else value
    return name.lower() == "localhost" or _is_loopback(name)


MAX_CONNECTIONS = 16
OPERATOR_CONNECTIONS = 2
MAX_PENDING = 16
REQUEST_DEADLINE_S = 5.0
WRITE_TIMEOUT_S = 5.0
KEEPALIVE_S = 15.0


def _sha256_source(text: str) -> str:
    return "'sha256-" + base64.b64encode(hashlib.sha256(text.encode()).digest()).decode() + "'"


def _page() -> tuple[bytes, str]:
    """The page, assembled from the packaged assets, and a Content-Security-Policy that allows exactly its
    own inline style and script and connections to this server only."""
    static = resources.files(__package__) / "static"
    html = (static / "index.html").read_text(encoding="utf-8")
    css = (static / "monitor.css").read_text(encoding="utf-8")
    js = (static / "monitor.js").read_text(encoding="utf-8")
    return html.replace("/*STYLE*/", css).replace("/*SCRIPT*/", js).encode(), (
        f"default-src 'none'; script-src {_sha256_source(js)}; style-src {_sha256_source(css)}; "
        "connect-src 'self'; img-src 'self'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'"
    )


class _DeadlineReader(io.RawIOBase):
    """A connection's incoming bytes, every read waiting only for what is left of the request's deadline
    (a socket timeout alone restarts at each byte, so a client sending one byte every few seconds would
    never be timed out)."""

    def __init__(self, sock: socket.socket, deadline: float) -> None:
        self.sock = sock
        self.deadline = deadline

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
        left = self.deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError("the request did not arrive within its deadline")
        self.sock.settimeout(left)
        try:
            return self.sock.recv_into(buffer)
        finally:
            self.sock.settimeout(WRITE_TIMEOUT_S)


class MonitorServer(ThreadingHTTPServer):
    daemon_threads = True
    block_on_close = False
    request_queue_size = 64

    def __init__(
        self,
        address: MonitorAddress,
        bus: EventBus,
        *,
        token: str | None,
        max_pending: int = MAX_PENDING,
        request_deadline_s: float = REQUEST_DEADLINE_S,
    ) -> None:
        self.address_family = address.family
        self.bus = bus
        self.token = token
        self.token_required = token is not None and not address.loopback
        self.loopback = address.loopback
        self.max_pending = max_pending
        self.request_deadline_s = request_deadline_s
        self.page, self.csp = _page()  # assembled once
        self.active = 0  # requests answered, in the shared places
        self.active_operator = 0  # and in the places kept for the token
        self.rejected = 0
        self.dropped = 0  # connections closed before their request arrived whole
        self.errors = 0
        self.closing = False
        self._pending: dict[socket.socket, float] = {}  # waiting for their request -> deadline, oldest first
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        super().__init__((address.host, address.port), _Handler)

    def server_bind(self) -> None:
        # HTTPServer.server_bind would look the host's name up (getfqdn): slow and pointless here
        socketserver.TCPServer.server_bind(self)
        self.server_name, self.server_port = str(self.server_address[0]), int(self.server_address[1])

    @property
    def port(self) -> int:
        return int(self.server_address[1])

    def start(self) -> None:
        self._thread = threading.Thread(
            target=self.serve_forever, kwargs={"poll_interval": 0.25}, name="monitor-http", daemon=True
        )
        self._thread.start()

    def close(self) -> None:
        self.closing = True
        self.shutdown()
        self.server_close()
        with self._lock:
            for sock in self._pending:
                with contextlib.suppress(OSError):
                    sock.shutdown(socket.SHUT_RDWR)

    # ---------------------------------------------------------------------- requests on their way

    def verify_request(self, request: Any, client_address: Any) -> bool:
        """Every connection is let in; when `max_pending` are still sending their request, the oldest of
        them is closed to make room (it had the longest time and has still not finished)."""
        with self._lock:
            while self._pending and len(self._pending) >= self.max_pending:
                oldest = next(iter(self._pending))
                del self._pending[oldest]
                self.dropped += 1
                with contextlib.suppress(OSError):
                    oldest.shutdown(socket.SHUT_RDWR)  # its handler's read returns at once
            self._pending[request] = time.monotonic() + self.request_deadline_s
        return True

    def request_deadline(self, request: socket.socket) -> float:
        with self._lock:
            return self._pending.get(request, 0.0)  # already pushed out: no time left

    def request_arrived(self, request: socket.socket) -> None:
        with self._lock:
            self._pending.pop(request, None)

    def shutdown_request(self, request: Any) -> None:
        with self._lock:  # out of the table before closing: a socket is shut down only while it is open
            if self._pending.pop(request, None) is not None:
                self.dropped += 1  # its request never arrived whole (too late, or the client gave up)
        super().shutdown_request(request)

    # ---------------------------------------------------------------------- places to be answered

    @contextlib.contextmanager
    def place(self, operator: bool) -> Iterator[bool]:
        """A place to answer a request in: a shared one, else for a token holder one of those kept for
        the token. Yields False (and counts a rejection) when there is none."""
        with self._lock:
            shared = self.active < MAX_CONNECTIONS
            kept = not shared and operator and self.active_operator < OPERATOR_CONNECTIONS
            self.active += shared
            self.active_operator += kept
            self.rejected += not (shared or kept)
        try:
            yield shared or kept
        finally:
            with self._lock:
                self.active -= shared
                self.active_operator -= kept

    def counts(self) -> dict[str, Any]:
        with self._lock:
            return {
                "connections": self.active + self.active_operator,
                "max_connections": MAX_CONNECTIONS,
                "operator_connections": OPERATOR_CONNECTIONS,
                "pending_requests": len(self._pending),
                "max_pending_requests": self.max_pending,
                "request_deadline_s": self.request_deadline_s,
                "rejected_connections": self.rejected,
                "dropped_requests": self.dropped,
            }

    def handle_error(self, request: Any, client_address: Any) -> None:
        self.errors += 1  # never a traceback on the session's terminal


class _Handler(BaseHTTPRequestHandler):
    server: MonitorServer
    server_version = "protocol-runner-monitor"
    sys_version = ""
    protocol_version = "HTTP/1.0"
    timeout = WRITE_TIMEOUT_S
    error_message_format = "%(code)d %(message)s\n"
    error_content_type = "text/plain; charset=utf-8"

    def setup(self) -> None:
        super().setup()
        self.rfile.close()  # the plain socket file: reads wait per byte, not per request
        deadline = self.server.request_deadline(self.connection)
        self.rfile = io.BufferedReader(_DeadlineReader(self.connection, deadline))

    def parse_request(self) -> bool:
        ok = super().parse_request()  # a late request raises TimeoutError: the stdlib closes quietly
        self.server.request_arrived(self.connection)
        return ok

    def log_message(self, format: str, *args: Any) -> None:
        return None  # the terminal belongs to the session

    def do_GET(self) -> None:
        url = urlsplit(self.path)
        srv = self.server
        if srv.loopback and not is_loopback_host_header(self.headers.get("Host", "localhost")):
            self._text(403, "this monitor answers only to localhost / 127.0.0.1\n")
            return
        operator = False
        if srv.token is not None:
            given = parse_qs(url.query).get("token", [""])[0]
            operator = hmac.compare_digest(given.encode(), srv.token.encode())
        if srv.token_required and not operator:
            self._text(403, "this monitor needs the token printed on the session's terminal\n")
            return
        if url.path not in ("/", "/index.html", "/events", "/status"):
            self._text(404, "not found: the monitor serves /, /events and /status only\n")
            return
        with srv.place(operator) as admitted:
            if not admitted:
                self._text(
                    503,
                    f"too many connections to the monitor (limit {MAX_CONNECTIONS}); the URL printed "
                    "on the session's terminal, with its token, has places kept for it\n",
                )
            else:
                self._answer(url.path)

    def _answer(self, path: str) -> None:
        srv = self.server
        if path in ("/", "/index.html"):
            self._send(200, "text/html; charset=utf-8", srv.page, csp=srv.csp)
        elif path == "/events":
            self._stream()
        else:
            status = srv.bus.status()
            status["monitor"] = srv.counts()
            self._send(200, "application/json", dumps(status).encode())

    def _text(self, code: int, message: str) -> None:
        self._send(code, "text/plain; charset=utf-8", message.encode())

    def _headers(self, code: int, content_type: str, *, csp: str | None = None) -> None:
        self.send_response(code)
        self.send_header("Content-Type", content_type)
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Referrer-Policy", "no-referrer")
        self.send_header("Content-Security-Policy", csp or "default-src 'none'; frame-ancestors 'none'")

    def _send(self, code: int, content_type: str, body: bytes, *, csp: str | None = None) -> None:
        self._headers(code, content_type, csp=csp)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def _peer_gone(self) -> bool:
        """Has the client closed its end? (A stream client never sends anything after its request.)"""
        try:
            readable, _, _ = select.select([self.connection], [], [], 0)
            return bool(readable) and self.connection.recv(1, socket.MSG_PEEK) == b""
        except (OSError, ValueError):
            return True

    def _stream(self) -> None:
        bus = self.server.bus
        client = bus.subscribe(self.connection)
        try:
            self._headers(200, "text/event-stream; charset=utf-8")
            self.end_headers()
            self.wfile.write(b"retry: 3000\n\n")
            last = time.monotonic()
            while True:
                try:
                    data = client.queue.get(timeout=1.0)
                except queue.Empty:
                    if client.dropped or self.server.closing or self._peer_gone():
                        return
                    if time.monotonic() - last > KEEPALIVE_S:
                        self.wfile.write(b": keepalive\n\n")
                        last = time.monotonic()
                    continue
                if data is None:
                    return
                self.wfile.write(data)
                last = time.monotonic()
        except (OSError, ValueError):
            return  # the client went away, or was dropped for reading too slowly
        finally:
            bus.unsubscribe(client)
            with contextlib.suppress(OSError):
                self.connection.shutdown(socket.SHUT_RDWR)
