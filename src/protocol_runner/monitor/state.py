"""What a page that connects mid-session needs: `hello` with `snapshot()`, then `replay()`, the samples of
each joint's last `TRACE_WINDOW_S` seconds and current run, kept as encoded JSON fragments (a connection
costs string joins, not re-encoding).
"""

from __future__ import annotations

import json
import math
from collections import deque
from dataclasses import dataclass
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
