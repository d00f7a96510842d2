"""`--monitor`: open the page's server before the session starts (a bind failure is exit 2 before the
session folder exists), attach it to the session, publish `session_end` and stop it (docs/monitor.md).
"""

from __future__ import annotations

import contextlib
import errno
import secrets
from collections.abc import Callable
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

from ..errors import EXIT_INTERRUPTED, EXIT_OK, InvalidInput, UserError
from .bus import EventBus, JournalTail
from .live import SAMPLE_RATE_HZ, LivePublisher, MonitoredOperator, SampleTap
from .server import MonitorAddress, MonitorServer, parse_address

if TYPE_CHECKING:
    from ..protocol.plan_steps import Plan
    from ..session.setup import SessionInfo
    from ..steps.context import Bench
    from ..steps.operator import Operator
    from .publisher import Publisher


_BIND_ERRORS = {
    errno.EADDRINUSE: "port {port} on {host} is already in use; the session was not started. Pick another "
    "port, e.g. --monitor {host}:{next}",
    errno.EACCES: "not allowed to listen on port {port} (ports below 1024 need privileges); the session was "
    "not started. Pick a port from 1024 up, e.g. --monitor 8765",
    errno.EADDRNOTAVAIL: "{host} is not an address of this machine; the session was not started",
    0: "cannot listen on {host}:{port} ({why}); the session was not started",
}


class Monitor:
    def __init__(self, address: MonitorAddress, bus: EventBus, server: MonitorServer, token: str):
        self.address = address
        self.bus = bus
        self.server = server
        self.token = token

    @classmethod
    def open(cls, spec: str, *, say: Callable[[str], None]) -> Monitor:
        address = parse_address(spec)
        token = secrets.token_urlsafe(18)
        bus = EventBus()
        try:
            server = MonitorServer(address, bus, token=token)
        except OSError as exc:
            text = _BIND_ERRORS.get(exc.errno or 0, _BIND_ERRORS[0])
            host, port, why = address.host, address.port, exc.strerror or exc
            raise InvalidInput(
                "--monitor: " + text.format(host=host, port=port, next=port + 1, why=why)
            ) from None
        bus.start()
        server.start()
        monitor = cls(address, bus, server, token)
        if address.loopback:
            say(
                f"monitor: {monitor.url} (read-only; this machine only; the token is not needed to watch, "
                "but keeps places for this URL when other clients fill the monitor)"
            )
        else:
            say(
                f"monitor: {monitor.url}\n  read-only, reachable from the network on {address.host}: the "
                "token in this URL is its only key and is printed only here"
            )
        return monitor

    @property
    def port(self) -> int:
        return self.server.port

    @property
    def url(self) -> str:
        return f"http://{self.address.url_host()}:{self.port}/?token={self.token}"

    def attach(
        self,
        session_dir: Path,
        info: SessionInfo,
        plan: Plan,
        bench: Bench,
        operator: Operator,
        *,
        resumed: bool = False,
    ) -> tuple[Publisher, Operator]:
        """Hook the session up; returns the runner's publisher and the operator to use."""
        publisher = LivePublisher(self.bus)
        rig = bench.rig
        tap = SampleTap(tuple(rig.joints), self.bus.publish_samples, scan_channels=rig.scan_channels)
        rig.tap = tap
        publisher.taps.append(tap)
        self.bus.add_source(JournalTail(session_dir / "journal.jsonl"))
        self.bus.publish(
            {
                "type": "session",
                "protocol": info.protocol_name,
                "mode": info.mode + (" (real time)" if info.realtime else ""),
                "folder": str(session_dir),
                "seed": info.seed,
                "only": list(info.only),
                "resumed": resumed,
                "joints": list(tap.names),
                "steps": len(plan.steps),
                "sample_rate_hz": SAMPLE_RATE_HZ,
            }
        )
        from ..session.operator import AutoOperator

        watched = operator if isinstance(operator, AutoOperator) else MonitoredOperator(operator, self.bus)
        return publisher, watched

    def end(self, exc: BaseException | None) -> None:
        """Publish `session_end`: complete, or why the session stopped."""
        msg: dict[str, Any] = {"type": "session_end"}
        if exc is None:
            msg.update(status="complete", exit_code=EXIT_OK, message="the session finished")
        elif isinstance(exc, UserError):
            status = {2: "stopped", 3: "hardware unavailable", 4: "stopped by a check", 130: "interrupted"}
            msg.update(
                status=status.get(exc.exit_code, "stopped"), exit_code=exc.exit_code, message=exc.message
            )
        elif isinstance(exc, KeyboardInterrupt):
            msg.update(status="interrupted", exit_code=EXIT_INTERRUPTED, message="interrupted")
        else:
            msg.update(status="failed", exit_code=1, message=f"internal error: {exc!r}")
        self.bus.publish(msg)

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.bus.close()
        with contextlib.suppress(Exception):
            self.server.close()

    def __enter__(self) -> Monitor:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.end(exc)
        self.close()
