"""The event bus between the session and the page's clients (docs/monitor.md "Never in the way of the
output loop"): `publish` and `publish_samples` only append to a deque (and set an event), never take a lock
held by anyone else, never do I/O; a pump thread merges, numbers, encodes and fans out to bounded queues.
A page that connects mid-session receives `hello` with `SessionState.snapshot()`, then `replay()`: the
samples of each joint's last `TRACE_WINDOW_S` seconds and current run, kept as encoded JSON fragments (a
connection costs string joins, not re-encoding).
"""

from __future__ import annotations

import contextlib
import json
import math
import queue
import socket
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

TRACE_WINDOW_S = 15.0
"""Seconds of the live traces."""
MAX_REPLAY_POINTS = 12_000
"""Bound on the samples kept for a new client (about 10 min of one joint at 20 Hz)."""
MAX_CHUNK_POINTS = 2_000
KEPT_VERDICTS = 12
KEPT_EVENTS = 30

_COMPACT = (",", ":")


def dumps(obj: object) -> str:
    """Compact JSON that a browser's JSON.parse accepts: NaN and infinities become null."""
    try:
        return json.dumps(obj, separators=_COMPACT, allow_nan=False, default=str)
    except ValueError:
        return json.dumps(_finite(obj), separators=_COMPACT, allow_nan=False, default=str)


def _finite(obj: object) -> object:
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    return obj


def encode_samples(msg: dict[str, Any]) -> tuple[str, str]:
    """(the message's JSON text, the JSON of its points list), the points encoded only once."""
    points = dumps(msg["points"])
    head = dumps({k: v for k, v in msg.items() if k != "points"})
    return f'{head[:-1]},"points":{points}}}', points


@dataclass
class _Chunk:
    """Consecutive samples of one joint and one run, merged (other joints' samples may come between)."""

    joint: str
    where: str
    step: str
    phase: str
    t_last: float
    n_points: int
    fragments: list[str]

    def encode(self) -> str:
        head = dumps(
            {
                "type": "samples",
                "replay": True,
                "step": self.step,
                "joint": self.joint,
                "where": self.where,
                "phase": self.phase,
            }
        )
        return f'{head[:-1]},"points":[{",".join(self.fragments)}]}}'


class SessionState:
    def __init__(self) -> None:
        self.session: dict[str, Any] | None = None
        self.step: dict[str, Any] | None = None
        self.progress: dict[str, Any] | None = None
        self.operator: dict[str, Any] | None = None
        self.ended: dict[str, Any] | None = None
        self.verdicts: deque[dict[str, Any]] = deque(maxlen=KEPT_VERDICTS)
        self.events: deque[dict[str, Any]] = deque(maxlen=KEPT_EVENTS)
        self.n_points = 0
        self._chunks: list[_Chunk] = []
        self._latest_t: dict[str, float] = {}
        self._current_run: dict[str, str] = {}
        self._open: dict[str, _Chunk] = {}  # each joint's newest chunk

    def apply(self, msg: dict[str, Any], points_json: str | None = None) -> None:
        kind = msg.get("type")
        if kind == "samples" and points_json is not None:
            self._keep_samples(msg, points_json)
        elif kind == "session":
            self.session = msg
        elif kind == "step_start":
            self.step = msg
        elif kind == "progress":
            self.progress = msg
        elif kind == "operator_wait":
            self.operator = msg if msg.get("waiting") else None
        elif kind == "verdict":
            self.verdicts.append(msg)
        elif kind == "event":
            self.events.append(msg)
        elif kind == "session_end":
            self.ended = msg
            self.operator = None

    def snapshot(self) -> dict[str, Any]:
        return {
            "session": self.session,
            "step": self.step,
            "progress": self.progress,
            "operator": self.operator,
            "ended": self.ended,
            "verdicts": list(self.verdicts),
            "events": list(self.events),
            "trace_window_s": TRACE_WINDOW_S,
            "points_published": self.n_points,
        }

    def replay(self) -> list[str]:
        """The kept samples as `samples` messages (marked "replay": true), oldest first."""
        return [chunk.encode() for chunk in self._chunks]

    # ------------------------------------------------------------------------------------ samples

    def _keep_samples(self, msg: dict[str, Any], points_json: str) -> None:
        points = msg["points"]
        if not points:
            return
        joint, where = str(msg["joint"]), str(msg["where"])
        t_last = float(points[-1][0])
        self.n_points += len(points)
        self._latest_t[joint] = max(t_last, self._latest_t.get(joint, t_last))
        if msg.get("phase") == "run":
            self._current_run[joint] = where
        fragment = points_json[1:-1]
        last = self._open.get(joint)  # the joints' samples alternate: each joint's own chunk grows
        if last is not None and last.where == where and last.n_points + len(points) <= MAX_CHUNK_POINTS:
            last.fragments.append(fragment)
            last.n_points += len(points)
            last.t_last = t_last
        else:
            step, phase = str(msg.get("step", "")), str(msg.get("phase", ""))
            chunk = _Chunk(joint, where, step, phase, t_last, len(points), [fragment])
            self._chunks.append(chunk)
            self._open[joint] = chunk
        self._prune()

    def _prune(self) -> None:
        def wanted(c: _Chunk) -> bool:
            recent = c.t_last >= self._latest_t.get(c.joint, c.t_last) - TRACE_WINDOW_S
            return recent or self._current_run.get(c.joint) == c.where

        kept = [c for c in self._chunks if wanted(c)]
        total = sum(c.n_points for c in kept)
        while total > MAX_REPLAY_POINTS and len(kept) > 1:
            total -= kept.pop(0).n_points
        self._chunks = kept
        self._open = {j: c for j, c in self._open.items() if any(c is k for k in kept)}


INTERVAL_S = 0.05
"""The pump's cadence: at most 20 samples messages a second reach a page."""
CLIENT_QUEUE = 512
"""Messages waiting for one client before it counts as too slow and is dropped."""
SAMPLE_BACKLOG = 2_000
"""Samples messages waiting for the pump beyond which new ones are discarded."""
MAX_MERGED_POINTS = 2_000
"""Points of one samples message after merging: 100 s of one run at 20 Hz (older points of a longer burst
are left out of the live stream and counted in `trimmed_points`)."""


class Client:
    """One page's event stream: a bounded queue of encoded frames (None = the stream ends)."""

    def __init__(self, sock: socket.socket | None, size: int) -> None:
        self.sock = sock
        self.queue: queue.Queue[bytes | None] = queue.Queue(maxsize=size)
        self.dropped = False

    def kick(self) -> None:
        """Unblock a handler stuck writing to a client that does not read."""
        if self.sock is not None:
            with contextlib.suppress(OSError):
                self.sock.shutdown(socket.SHUT_RDWR)


def frame(text: str, seq: int | None = None) -> bytes:
    """One Server-Sent Events frame (the JSON text never contains a newline)."""
    head = f"id: {seq}\n" if seq is not None else ""
    return f"{head}data: {text}\n\n".encode()


class EventBus:
    def __init__(self, *, sample_backlog: int = SAMPLE_BACKLOG) -> None:
        self.state = SessionState()
        self.sample_backlog = sample_backlog
        self.dropped_samples = 0
        self.trimmed_points = 0
        self.dropped_clients = 0
        self.seq = 0
        self._inbox: deque[dict[str, Any]] = deque()
        self._wake = threading.Event()
        self._lock = threading.Lock()
        self._clients: list[Client] = []
        self._sources: list[Callable[[], Iterable[dict[str, Any]]]] = []
        self._stopping = False
        self._busy = False
        self._thread: threading.Thread | None = None

    # ------------------------------------------------------------------------ the session's side

    def publish(self, msg: dict[str, Any]) -> None:
        """Queue a control message (never discarded) and wake the pump."""
        msg.setdefault("t_wall", round(time.time(), 3))
        self._inbox.append(msg)
        self._wake.set()

    def publish_samples(self, msg: dict[str, Any]) -> None:
        """Queue a samples message, or discard it if the pump is `sample_backlog` messages behind."""
        if len(self._inbox) >= self.sample_backlog:
            self.dropped_samples += 1
            return
        self._inbox.append(msg)

    def add_source(self, source: Callable[[], Iterable[dict[str, Any]]]) -> None:
        """A poller the pump calls every cycle (the journal's new events)."""
        self._sources.append(source)

    # ------------------------------------------------------------------------- the clients' side

    def subscribe(self, sock: socket.socket | None = None) -> Client:
        """A new client: its queue starts with `hello` (the snapshot) and the kept samples."""
        client = Client(sock, CLIENT_QUEUE)
        with self._lock:
            hello = {"type": "hello", "seq": self.seq, "snapshot": self.snapshot()}
            client.queue.put_nowait(frame(dumps(hello), self.seq))
            for text in self.state.replay()[-(CLIENT_QUEUE // 2) :]:
                client.queue.put_nowait(frame(text))
            self._clients.append(client)
        return client

    def unsubscribe(self, client: Client) -> None:
        with self._lock, contextlib.suppress(ValueError):  # already dropped
            self._clients.remove(client)

    def snapshot(self) -> dict[str, Any]:
        snap = self.state.snapshot()
        snap["dropped_samples"] = self.dropped_samples
        snap["trimmed_points"] = self.trimmed_points
        return snap

    def status(self) -> dict[str, Any]:
        with self._lock:
            out = self.snapshot()
            out["clients"] = len(self._clients)
            out["dropped_clients"] = self.dropped_clients
            out["seq"] = self.seq
        return out

    # ------------------------------------------------------------------------------------ pump

    def start(self) -> None:
        self._thread = threading.Thread(target=self._pump, name="monitor-bus", daemon=True)
        self._thread.start()

    def _pump(self) -> None:
        while not self._stopping:
            self._wake.wait(INTERVAL_S)
            self._wake.clear()
            self._busy = True
            try:
                self.cycle()
            finally:
                self._busy = False

    def cycle(self) -> None:
        """Deliver what the sources and the session queued since the last cycle, in order."""
        self._poll_sources()
        items: list[dict[str, Any]] = []
        # the samples messages since the last control message, by (joint, run): the joints' messages
        # alternate, each is merged with its own joint's
        open_runs: dict[tuple[str, str], dict[str, Any]] = {}
        while self._inbox:
            msg = self._inbox.popleft()
            if msg.get("type") != "samples":
                open_runs.clear()
                items.append(msg)
                continue
            key = (str(msg["joint"]), str(msg["where"]))
            last = open_runs.get(key)
            if last is not None:
                merged = last["points"] + msg["points"]
                self.trimmed_points += max(0, len(merged) - MAX_MERGED_POINTS)
                last["points"] = merged[-MAX_MERGED_POINTS:]
                continue
            open_runs[key] = msg
            items.append(msg)
        for msg in items:
            if msg.get("type") == "session_end":
                self._poll_sources()  # the journal's last events come before the end
            self._deliver(msg)

    def _poll_sources(self) -> None:
        for source in self._sources:
            try:
                for msg in source():
                    self._deliver(msg)
            except Exception:  # a broken source (unreadable journal) must not stop the stream
                continue

    def _deliver(self, msg: dict[str, Any]) -> None:
        with self._lock:
            self.seq += 1
            msg["seq"] = self.seq
            if msg.get("type") == "samples":
                text, points = encode_samples(msg)
                self.state.apply(msg, points)
            else:
                text = dumps(msg)
                self.state.apply(msg)
            data = frame(text, self.seq)
            for client in list(self._clients):
                try:
                    client.queue.put_nowait(data)
                except queue.Full:
                    self._drop(client)

    def _drop(self, client: Client) -> None:
        client.dropped = True
        self.dropped_clients += 1
        self._clients.remove(client)
        client.kick()

    # --------------------------------------------------------------------------------- closing

    def flush(self, timeout_s: float = 2.0, *, clients: bool = False) -> bool:
        """Wait until every message published so far is delivered (the state and `/status` show it), and
        with `clients` until the clients have taken it too; at most `timeout_s`. True if it was."""
        deadline = time.monotonic() + timeout_s
        if self._thread is None:
            self.cycle()
        self._wake.set()

        def pending() -> bool:  # the pump sets _busy before it pops the inbox: never both seen clear early
            return bool(self._inbox or self._busy or (clients and self._pending_output()))

        while pending():
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.01)
        return True

    def close(self, flush_s: float = 2.0) -> None:
        """Deliver what is queued, give the clients up to `flush_s` to take it, then end every stream."""
        self.flush(flush_s, clients=True)
        self._stopping = True
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        with self._lock:
            clients, self._clients = self._clients, []
        for client in clients:
            try:
                client.queue.put_nowait(None)
            except queue.Full:
                client.kick()

    def _pending_output(self) -> bool:
        with self._lock:
            return any(not c.queue.empty() for c in self._clients)


MAX_READ = 1 << 20
"""Bytes read per poll at most (a journal grows by a few hundred bytes per step)."""


class JournalTail:
    """The journal's new event and invalidation records as `event` messages: a source the bus polls every
    cycle (a torn or foreign line is skipped, as the journal itself does)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._offset = path.stat().st_size if path.exists() else 0  # the past is not replayed
        self._rest = b""

    def __call__(self) -> list[dict[str, Any]]:
        try:
            with self.path.open("rb") as f:
                f.seek(self._offset)
                data = f.read(MAX_READ)
        except OSError:
            return []
        if not data:
            return []
        self._offset += len(data)
        lines = (self._rest + data).split(b"\n")
        self._rest = lines.pop()  # an unfinished last line waits for the next poll
        out: list[dict[str, Any]] = []
        for line in lines:
            try:
                rec = json.loads(line)
            except ValueError:
                continue
            if not isinstance(rec, dict) or rec.get("record") not in ("event", "invalidate"):
                continue
            redo = rec["record"] == "invalidate"
            out.append(
                {
                    "type": "event",
                    "kind": "redo" if redo else str(rec.get("kind", "")),
                    "detail": f"{rec.get('step_id', '?')}: {rec.get('why', '')}"
                    if redo
                    else str(rec.get("detail", "")),
                    "t_utc": str(rec.get("t_utc", "")),
                }
            )
        return out
