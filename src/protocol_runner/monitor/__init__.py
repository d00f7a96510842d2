"""The live monitor (`--monitor [HOST:]PORT`): a read-only page that shows a running session.

    publisher.py     what the runner and steps call (a null version without a monitor)
    samples.py       the output loop's tap: decimated angle/torque samples (~20 Hz)
    bus.py           non-blocking publish, a pump thread, bounded per-client queues
    state.py         what a page connecting mid-session receives first
    journal_tail.py  the journal's events as messages
    live.py          hook calls -> messages (steps, progress and ETA, verdicts, operator waits)
    server.py        HTTP on a background thread: /, /events (Server-Sent Events), /status
    address.py       [HOST:]PORT, loopback or token
    service.py       open before the session, attach, end
    static/          the page: HTML, CSS and a small canvas script of our own

Messages are documented in docs/monitor.md.
"""

from __future__ import annotations

from ..events import NULL_PUBLISHER, NullPublisher, Publisher

__all__ = ["NULL_PUBLISHER", "NullPublisher", "Publisher"]  # the server: monitor.service.Monitor
