"""The live monitor (`--monitor [HOST:]PORT`): a read-only page that shows a running session.

    ../events.py     what the runner and steps call, `Publisher` (`NULL_PUBLISHER` without a monitor)
    bus.py           non-blocking publish, a pump thread, bounded per-client queues; the journal's events;
                     what a page connecting mid-session receives first
    live.py          hook calls -> messages (steps, progress and ETA, verdicts, operator waits); the
                     output loop's tap: decimated angle/torque samples (~20 Hz)
    server.py        HTTP on a background thread: /, /events (Server-Sent Events), /status; [HOST:]PORT
    service.py       open before the session, attach, end
    static/          the page: HTML, CSS and a small canvas script of our own

Messages are documented in docs/monitor.md.
"""
