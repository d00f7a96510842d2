"""The monitor's server on its own: read-only, loopback or token, a connection cap, garbage-proof, and a
page that needs nothing from the internet."""

from __future__ import annotations

import base64
import hashlib
import json
import re
import socket
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from protocol_runner.cli import main
from protocol_runner.monitor.server import MAX_CONNECTIONS, WRITE_TIMEOUT_S
from protocol_runner.monitor.service import Monitor

from .sse import Stream, get, status


@pytest.fixture
def monitor() -> Iterator[Monitor]:
    said: list[str] = []
    with Monitor.open("127.0.0.1:0", say=said.append) as live:
        yield live


def base(live: Monitor) -> str:
    return f"http://127.0.0.1:{live.port}/"


def raw(port: int, data: bytes, *, timeout: float = 5.0) -> bytes:
    """Send raw bytes, return everything the server answers until it closes."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        s.sendall(data)
        out = b""
        while chunk := s.recv(65536):
            out += chunk
        return out


def test_page_is_self_contained_and_locked_down(monitor: Monitor) -> None:
    code, body = get(base(monitor))
    assert code == 200
    page = body.decode()
    assert "new EventSource(" in page and 'getContext("2d")' in page
    assert not re.search(r"(src|href)=\"https?://", page), "the page must not load anything from elsewhere"
    assert "https://" not in page and "http://" not in page
    with socket.create_connection(("127.0.0.1", monitor.port)) as s:
        s.sendall(b"GET / HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n")
        head = s.recv(65536).split(b"\r\n\r\n", 1)[0].decode()
    csp = re.search(r"Content-Security-Policy: (.*)", head)
    assert csp is not None
    script = re.search(r"<script>(.*)</script>", page, re.S)
    assert script is not None
    digest = base64.b64encode(hashlib.sha256(script.group(1).encode()).digest()).decode()
    assert f"script-src 'sha256-{digest}'" in csp.group(1)  # only our own inline script may run
    assert "connect-src 'self'" in csp.group(1)


def test_only_three_paths_and_only_get(monitor: Monitor) -> None:
    assert get(base(monitor) + "journal.jsonl")[0] == 404
    assert get(base(monitor) + "../session.json")[0] == 404
    assert get(base(monitor) + "units/")[0] == 404
    reply = raw(monitor.port, b"POST /status HTTP/1.0\r\nHost: 127.0.0.1\r\nContent-Length: 2\r\n\r\n{}")
    assert reply.startswith(b"HTTP/1.0 501")
    reply = raw(monitor.port, b"PUT / HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n")
    assert reply.startswith(b"HTTP/1.0 501")


def test_status_is_json_with_the_latest_of_each_message(monitor: Monitor) -> None:
    monitor.bus.publish({"type": "session", "protocol": "p", "mode": "dry-run", "folder": "/tmp/x"})
    monitor.bus.publish({"type": "step_start", "step": "trial:a", "kind": "trial"})
    monitor.bus.publish({"type": "verdict", "step": "cal:s:before", "verdict": "pass"})
    assert monitor.bus.flush(30)  # delivered: /status shows it
    s = status(base(monitor))
    assert s["session"]["protocol"] == "p"
    assert s["step"]["step"] == "trial:a"
    assert s["verdicts"][0]["verdict"] == "pass"
    assert s["ended"] is None and s["clients"] == 0


def test_loopback_monitor_refuses_a_foreign_host_header(monitor: Monitor) -> None:
    # a web page elsewhere that rebinds its DNS name to 127.0.0.1 sends its own name as Host
    code, _ = get(base(monitor) + "status", headers={"Host": "evil.example:8765"})
    assert code == 403
    assert get(base(monitor) + "status", headers={"Host": f"localhost:{monitor.port}"})[0] == 200


def test_non_loopback_needs_the_token_printed_once() -> None:
    said: list[str] = []
    with Monitor.open("0.0.0.0:0", say=said.append) as live:
        assert live.token is not None and len(live.token) >= 20
        announced = "\n".join(said)
        assert announced.count(live.token) == 1
        url = f"http://127.0.0.1:{live.port}/"
        for path in ("", "status", "events"):
            assert get(url + path)[0] == 403
            assert get(url + path + "?token=wrong")[0] == 403
        code, body = get(url + "status?token=" + live.token)
        assert code == 200 and "session" in json.loads(body)
        code, body = get(url + "?token=" + live.token)
        assert code == 200 and b"EventSource" in body
        assert live.token not in get(url + "status?token=" + live.token)[1].decode()  # never echoed


def test_port_in_use_is_exit_2_naming_the_port_before_anything_starts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with socket.socket() as holder:
        holder.bind(("127.0.0.1", 0))
        holder.listen()
        port = holder.getsockname()[1]
        session = tmp_path / "s"
        code = main(
            [
                "knee_phase1.yaml",
                "--dry-run",
                "--session",
                str(session),
                "--monitor",
                f"127.0.0.1:{port}",
            ]
        )
    err = capsys.readouterr().err
    assert code == 2
    assert f"port {port}" in err and "already in use" in err and "--monitor" in err
    assert "Traceback" not in err
    assert not session.exists()  # the session did not start


def test_bad_monitor_arguments_are_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for spec, words in (
        ("http", "not a port number"),
        ("70000", "out of range"),
        ("::1:8765", "brackets"),
        ("no-such-host.invalid:8765", "cannot resolve"),
    ):
        code = main(["knee_phase1.yaml", "--dry-run", "--session", str(tmp_path / "s"), "--monitor", spec])
        err = capsys.readouterr().err
        assert code == 2, spec
        assert words in err and "Traceback" not in err, err
    assert main(["--plan", "knee_phase1.yaml", "--monitor", "8765"]) == 2
    assert "--monitor watches a session" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


def test_connection_cap_answers_503_and_the_server_recovers(monitor: Monitor) -> None:
    streams = [Stream("127.0.0.1", monitor.port) for _ in range(MAX_CONNECTIONS)]
    try:
        for s in streams:
            s.wait_for("hello")
        reply = raw(monitor.port, b"GET /status HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n")
        assert reply.startswith(b"HTTP/1.0 503") and b"too many connections" in reply
        t0 = time.perf_counter()
        for k in range(200):
            monitor.bus.publish({"type": "event", "kind": "test", "detail": str(k)})
        # publishing queues and returns: 200 messages take microseconds, while waiting on a client that
        # reads nothing would take a whole write timeout (half of it is generous for a loaded machine)
        assert time.perf_counter() - t0 < WRITE_TIMEOUT_S / 2
        streams[-1].wait_for("event")
    finally:
        for s in streams:
            s.close()
    deadline = time.monotonic() + 20  # a closed stream frees its slot at its next write (keep-alive)
    while time.monotonic() < deadline:
        if get(base(monitor) + "status")[0] == 200:
            break
        time.sleep(0.05)
    s = status(base(monitor))
    assert s["monitor"]["rejected_connections"] >= 1


def test_hundreds_of_silent_connections_are_shed_and_the_server_recovers(monitor: Monitor) -> None:
    socks = []
    try:
        for _ in range(300):
            # a full listen backlog retries a connection after 1 s, then 3 s, ...: a generous timeout
            socks.append(socket.create_connection(("127.0.0.1", monitor.port), timeout=30))
        t0 = time.perf_counter()
        monitor.bus.publish({"type": "event", "kind": "still", "detail": "publishing"})
        assert time.perf_counter() - t0 < WRITE_TIMEOUT_S / 2  # at once; a silent peer would hold it longer
    finally:
        for s in socks:
            s.close()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        code, _ = get(base(monitor) + "status")
        if code == 200:
            break
        time.sleep(0.1)
    assert code == 200


@pytest.mark.parametrize(
    "garbage",
    [
        b"\x00\xff\xfe garbage \x01\r\n\r\n",
        b"GET\r\n\r\n",
        b"GET /status HTTP/9.9\r\n\r\n",
        b"GET /" + b"a" * 70000 + b" HTTP/1.0\r\n\r\n",
        b"GET /status HTTP/1.0\r\n" + b"X-Long: y\r\n" * 200 + b"\r\n",
        b"GET /events?token=%ff%fe HTTP/1.0\r\nHost: \xff\r\n\r\n",
    ],
)
def test_garbage_requests_do_not_break_the_server(monitor: Monitor, garbage: bytes) -> None:
    stream = Stream("127.0.0.1", monitor.port)
    stream.wait_for("hello")
    try:
        reply = raw(monitor.port, garbage)
        # an HTTP error status (a request line too broken to parse gets the bare "400 ..." of HTTP/0.9)
        assert reply == b"" or re.match(rb"(HTTP/1\.[01] )?[45]\d\d ", reply), reply[:80]
        monitor.bus.publish({"type": "event", "kind": "after", "detail": "garbage"})
        assert stream.wait_for("event")["kind"] == "after"  # the watching client did not notice
        assert get(base(monitor) + "status")[0] == 200
    finally:
        stream.close()


def test_a_silent_connection_is_closed_after_the_request_timeout(monitor: Monitor) -> None:
    with socket.create_connection(("127.0.0.1", monitor.port), timeout=15) as s:
        t0 = time.monotonic()
        assert s.recv(100) == b""  # the server hangs up on a client that never sends its request
        assert time.monotonic() - t0 < 10


def test_resume_with_a_monitor_and_a_missing_session_is_a_plain_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["--resume", str(tmp_path / "nothing"), "--monitor", "127.0.0.1:0"])
    err = capsys.readouterr().err
    assert code == 2
    assert "monitor: http://127.0.0.1:" in err  # served, then closed with the session's error
    assert "no such session directory" in err and "Traceback" not in err


def test_help_shows_the_monitor_flag_for_runs_and_resumes(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    assert "--resume SESSION_DIR [--yes] [--force] [--monitor [HOST:]PORT]" in out
    assert "--monitor [HOST:]PORT" in out and "127.0.0.1" in out
