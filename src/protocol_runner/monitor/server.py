"""The monitor's HTTP server: standard library only, on background threads, read-only.

Serves exactly three things: `/` (the page: HTML with its own CSS and script inlined, all shipped in
`monitor/static/`), `/events` (the Server-Sent Events stream of `bus.py`) and `/status` (the snapshot as
JSON). Every other path is 404, every method but GET is refused (501), nothing of the session folder is
served. At most `MAX_CONNECTIONS` connections are open at once; more are answered 503 and closed by the
accepting thread without starting a handler. A request must arrive within `REQUEST_TIMEOUT_S`, and a
write that blocks that long ends the connection. On a loopback bind the Host header must name loopback (no
DNS rebinding); on any other bind every request needs `?token=` (the token printed on the terminal).
"""

from __future__ import annotations

import base64
import contextlib
import hashlib
import hmac
import queue
import select
import socket
import socketserver
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from typing import Any
from urllib.parse import parse_qs, urlsplit

from .address import MonitorAddress, is_loopback_host_header
from .bus import EventBus
from .state import dumps

MAX_CONNECTIONS = 16
REQUEST_TIMEOUT_S = 5.0
KEEPALIVE_S = 15.0


def _sha256_source(text: str) -> str:
    return "'sha256-" + base64.b64encode(hashlib.sha256(text.encode()).digest()).decode() + "'"


class Page:
    """The page, assembled once from the packaged assets, with a Content-Security-Policy that allows
    exactly its own inline style and script and connections to this server only."""

    def __init__(self) -> None:
        static = resources.files(__package__) / "static"
        html = (static / "index.html").read_text(encoding="utf-8")
        css = (static / "monitor.css").read_text(encoding="utf-8")
        js = (static / "monitor.js").read_text(encoding="utf-8")
        self.body = html.replace("/*STYLE*/", css).replace("/*SCRIPT*/", js).encode()
        self.csp = (
            f"default-src 'none'; script-src {_sha256_source(js)}; style-src {_sha256_source(css)}; "
            "connect-src 'self'; img-src 'self'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'"
        )


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
        max_connections: int = MAX_CONNECTIONS,
    ) -> None:
        self.address_family = address.family
        self.bus = bus
        self.token = token
        self.loopback = address.loopback
        self.max_connections = max_connections
        self.page = Page()
        self.active = 0
        self.rejected = 0
        self.errors = 0
        self.closing = False
        self._count_lock = threading.Lock()
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

    # ---------------------------------------------------------------------- connection cap

    def verify_request(self, request: Any, client_address: Any) -> bool:
        with self._count_lock:
            if self.active < self.max_connections:
                self.active += 1
                return True
            self.rejected += 1
        body = f"too many connections to the monitor (limit {self.max_connections})\n".encode()
        with contextlib.suppress(OSError):
            request.settimeout(0.2)
            request.sendall(
                b"HTTP/1.0 503 Service Unavailable\r\nContent-Type: text/plain; charset=utf-8\r\n"
                + f"Content-Length: {len(body)}\r\nConnection: close\r\n\r\n".encode()
                + body
            )
        return False

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            with self._count_lock:
                self.active -= 1

    def handle_error(self, request: Any, client_address: Any) -> None:
        self.errors += 1  # never a traceback on the session's terminal


class _Handler(BaseHTTPRequestHandler):
    server: MonitorServer
    server_version = "protocol-runner-monitor"
    sys_version = ""
    protocol_version = "HTTP/1.0"
    timeout = REQUEST_TIMEOUT_S
    error_message_format = "%(code)d %(message)s\n"
    error_content_type = "text/plain; charset=utf-8"

    def log_message(self, format: str, *args: Any) -> None:
        return None  # the terminal belongs to the session

    def do_GET(self) -> None:
        url = urlsplit(self.path)
        srv = self.server
        if srv.loopback and not is_loopback_host_header(self.headers.get("Host", "localhost")):
            self._text(403, "this monitor answers only to localhost / 127.0.0.1\n")
            return
        if srv.token is not None:
            given = parse_qs(url.query).get("token", [""])[0]
            if not hmac.compare_digest(given.encode(), srv.token.encode()):
                self._text(403, "this monitor needs the token printed on the session's terminal\n")
                return
        if url.path in ("/", "/index.html"):
            self._send(200, "text/html; charset=utf-8", srv.page.body, csp=srv.page.csp)
        elif url.path == "/events":
            self._stream()
        elif url.path == "/status":
            status = srv.bus.status()
            status["monitor"] = {
                "connections": srv.active,
                "max_connections": srv.max_connections,
                "rejected_connections": srv.rejected,
            }
            self._send(200, "application/json", dumps(status).encode())
        else:
            self._text(404, "not found: the monitor serves /, /events and /status only\n")

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
