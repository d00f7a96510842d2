"""The journal's new event and invalidation records as `event` messages, polled by the bus every cycle
(a torn or foreign line is skipped, as the journal itself does).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

MAX_READ = 1 << 20
"""Bytes read per poll at most (a journal grows by a few hundred bytes per step)."""


class JournalTail:
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
