"""The bus: publishing never waits, a slow client is dropped, bursts are bounded, a late page catches up."""

from __future__ import annotations

import json
import socket
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from protocol_runner.errors import Interrupted
from protocol_runner.monitor.bus import (
    CLIENT_QUEUE,
    MAX_MERGED_POINTS,
    TRACE_WINDOW_S,
    Client,
    EventBus,
    JournalTail,
)
from protocol_runner.monitor.live import MonitoredOperator
from protocol_runner.monitor.service import Monitor
from protocol_runner.protocol.plan_steps import ChecklistStep
from protocol_runner.session.journal import Journal

from .sse import Stream, status


def drain(client: Client) -> list[dict[str, Any]]:
    out = []
    while not client.queue.empty():
        data = client.queue.get_nowait()
        assert data is not None
        line = next(x for x in data.decode().split("\n") if x.startswith("data: "))
        out.append(json.loads(line[6:]))
    return out


def samples(where: str, t: float, n: int = 2, step: str = "s", joint: str = "j") -> dict[str, Any]:
    pts = [[t + 0.05 * i, 1.0, 2.0, 3.0] for i in range(n)]
    phase = "run" if "(" not in where else "park"
    return {"type": "samples", "step": step, "joint": joint, "where": where, "phase": phase, "points": pts}


def test_a_client_that_stops_reading_is_dropped_and_publishing_never_waits() -> None:
    bus = EventBus()
    slow = bus.subscribe()  # never read
    fast = bus.subscribe()
    publishing = 0.0
    for k in range(3 * CLIENT_QUEUE):
        t0 = time.perf_counter()
        bus.publish({"type": "event", "kind": "n", "detail": str(k)})
        publishing += time.perf_counter() - t0
        if k % 50 == 0:
            bus.cycle()
            drain(fast)
    bus.cycle()
    assert slow.dropped and not fast.dropped
    assert bus.dropped_clients == 1 and bus.status()["clients"] == 1
    assert publishing / (3 * CLIENT_QUEUE) < 1e-3  # a deque append (µs), whatever the clients do


def test_a_real_socket_that_never_reads_is_dropped_while_others_get_everything() -> None:
    with Monitor.open("127.0.0.1:0", say=lambda s: None) as live:
        stuck = socket.socket()
        stuck.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        stuck.connect(("127.0.0.1", live.port))
        stuck.sendall(b"GET /events HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n")
        good = Stream("127.0.0.1", live.port)
        good.wait_for("hello")
        deadline = time.monotonic() + 5
        while status(f"http://127.0.0.1:{live.port}/")["clients"] < 2 and time.monotonic() < deadline:
            time.sleep(0.02)
        big = "x" * 8000
        publishing = 0.0
        n = 1500  # 12 MB: more than the socket buffers of the stuck client hold
        for k in range(n):
            t0 = time.perf_counter()
            live.bus.publish({"type": "event", "kind": "bulk", "detail": f"{k} {big}"})
            publishing += time.perf_counter() - t0
            if k % 100 == 0:
                time.sleep(0.02)  # let the pump and the good reader run
        assert publishing / n < 1e-3  # the stuck client's 5 s write timeout never reaches the publisher
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            got = [m for m in good.messages if m.get("kind") == "bulk"]
            if len(got) == n and status(f"http://127.0.0.1:{live.port}/")["clients"] == 1:
                break
            time.sleep(0.1)
        got = [int(m["detail"].split()[0]) for m in good.messages if m.get("kind") == "bulk"]
        assert got == list(range(n))  # the reading client lost nothing and kept the order
        assert status(f"http://127.0.0.1:{live.port}/")["clients"] == 1  # the stuck one is gone
        good.close()
        stuck.close()


def test_samples_beyond_the_backlog_are_discarded_but_control_messages_never() -> None:
    bus = EventBus(sample_backlog=10)
    for k in range(25):
        bus.publish_samples(samples("trial:a", float(k)))
    bus.publish({"type": "step_end", "step": "trial:a", "kind": "trial", "summary": ""})
    assert bus.dropped_samples == 15
    client = bus.subscribe()
    drain(client)
    bus.cycle()
    kinds = [m["type"] for m in drain(client)]
    assert kinds == ["samples", "step_end"]  # the ten queued samples merged into one message


def test_bursts_merge_per_run_keep_the_latest_points_and_never_cross_a_step() -> None:
    bus = EventBus(sample_backlog=10 * MAX_MERGED_POINTS)
    client = bus.subscribe()
    drain(client)
    n = MAX_MERGED_POINTS  # messages of 2 points: twice what one merged message keeps
    for k in range(n):
        bus.publish_samples(samples("trial:a", k * 0.1))
    bus.publish({"type": "step_end", "step": "trial:a", "kind": "trial", "summary": ""})
    bus.publish_samples(samples("trial:b", 100.0, step="trial:b"))
    bus.cycle()
    got = drain(client)
    assert [m["type"] for m in got] == ["samples", "step_end", "samples"]
    first = got[0]["points"]
    assert len(first) == MAX_MERGED_POINTS and bus.trimmed_points == MAX_MERGED_POINTS
    assert first[-1][0] == pytest.approx((n - 1) * 0.1 + 0.05)  # the newest kept
    assert got[2]["where"] == "trial:b"


def test_the_joints_alternating_samples_merge_per_joint_and_a_late_page_gets_every_joint() -> None:
    bus = EventBus()
    client = bus.subscribe()
    drain(client)
    for k in range(50):  # one message per joint and scan read, as the tap of a two-joint rig sends them
        bus.publish_samples(samples("trial:a", k * 0.1, joint="hip"))
        bus.publish_samples(samples("trial:a", k * 0.1, joint="knee"))
    bus.cycle()
    got = drain(client)
    assert [m["joint"] for m in got] == ["hip", "knee"]  # one merged message per joint, nothing lost
    assert all(len(m["points"]) == 100 for m in got)
    for k in range(50, 400):  # 40 s of the run, longer than the trace window
        bus.publish_samples(samples("trial:a", k * 0.1, joint="hip"))
        bus.publish_samples(samples("trial:a", k * 0.1, joint="knee"))
        bus.cycle()
    replay = [m for m in drain(bus.subscribe()) if m["type"] == "samples"]
    for joint in ("hip", "knee"):
        times = [p[0] for m in replay if m["joint"] == joint for p in m["points"]]
        assert len(times) == 800 and times == sorted(times)  # the whole current run of each joint
    assert len(replay) < 10  # in a few chunks, not one per message


def test_a_page_connecting_mid_run_gets_the_window_and_the_whole_current_run() -> None:
    bus = EventBus()
    bus.publish({"type": "step_start", "step": "trial:a", "kind": "trial"})
    for k in range(100):  # an old run, long before the trace window
        bus.publish_samples(samples("trial:old", k * 0.1))
        bus.cycle()
    for k in range(400):  # the current run: 40 s, longer than the window
        bus.publish_samples(samples("trial:a", 1000.0 + k * 0.1))
        bus.cycle()
    late = bus.subscribe()
    got = drain(late)
    assert got[0]["type"] == "hello" and got[0]["snapshot"]["step"]["step"] == "trial:a"
    replay = [m for m in got[1:] if m["type"] == "samples"]
    assert all(m.get("replay") for m in replay)
    assert {m["where"] for m in replay} == {"trial:a"}
    times = [p[0] for m in replay for p in m["points"]]
    assert min(times) == pytest.approx(1000.0) and max(times) > 1000.0 + TRACE_WINDOW_S
    assert times == sorted(times)


def test_nan_values_are_sent_as_null() -> None:
    bus = EventBus()
    client = bus.subscribe()
    drain(client)
    msg = samples("trial:a", 0.0)
    msg["points"][0][3] = float("nan")
    bus.publish_samples(msg)
    bus.cycle()
    (got,) = drain(client)
    assert got["points"][0][3] is None


def test_journal_events_become_messages_and_a_torn_line_waits(tmp_path: Path) -> None:
    path = tmp_path / "journal.jsonl"
    journal = Journal(path)
    journal.event("started", "before the monitor")
    tail = JournalTail(path)  # from the end: the past is not replayed
    assert tail() == []
    journal.event("resumed", "now")
    journal.invalidate("trial:a", "unit file missing")
    with path.open("ab") as f:
        f.write(b'{"record": "event", "kind": "half')
    got = tail()
    assert [(m["kind"], m["detail"]) for m in got] == [
        ("resumed", "now"),
        ("redo", "trial:a: unit file missing"),
    ]
    with path.open("ab") as f:
        f.write(b'", "detail": "done", "t_utc": "x"}\n')
    assert [m["kind"] for m in tail()] == ["half"]


class Person:
    def __init__(self) -> None:
        self.asked: list[str] = []

    def checklist(self, step: ChecklistStep) -> Any:
        self.asked.append(step.id)
        return "done"

    def accept_failed_check(self, message: str) -> bool:
        raise Interrupted("stopped by the operator")


def test_operator_prompts_show_a_waiting_banner_until_answered() -> None:
    bus = EventBus()
    client = bus.subscribe()
    drain(client)
    seen: list[bool] = []
    person = Person()
    op = MonitoredOperator(person, bus)  # type: ignore[arg-type]
    step = ChecklistStep(
        id="check:s:k1", kind="operator_checklist", set="s", title="Fit", items=("a",), brace="on"
    )

    def watch() -> None:
        bus.cycle()
        seen.extend(m["waiting"] for m in drain(client) if m["type"] == "operator_wait")

    assert op.checklist(step) == "done"
    watch()
    assert seen == [True, False] and person.asked == ["check:s:k1"]
    with pytest.raises(Interrupted):
        op.accept_failed_check("calibration check failed")
    watch()
    assert seen == [True, False, True, False]  # a stop while waiting clears the banner too
    assert bus.state.operator is None


def test_publish_from_many_threads_keeps_every_control_message() -> None:
    bus = EventBus()
    client = bus.subscribe()
    drain(client)

    def publisher(tag: int) -> None:
        for k in range(100):
            bus.publish({"type": "event", "kind": str(tag), "detail": str(k)})

    threads = [threading.Thread(target=publisher, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    bus.cycle()
    got = drain(client)
    assert len(got) == 400
    for tag in range(4):
        assert [m["detail"] for m in got if m["kind"] == str(tag)] == [str(k) for k in range(100)]
