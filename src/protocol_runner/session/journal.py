"""The session journal: an append-only JSON-lines file, fsynced after every record.

A unit is journaled as complete only after its file was atomically written (archive/units.py). Events
(started, interrupted, resumed, ...) end up in the archive's `/session/events`. A crash can leave a torn
last line: it is ignored on reading (it never described a complete unit).
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from ..archive.units import UnitRecord
from ..errors import InvalidInput
from .lock import open_nofollow, refuse_link


def utc_now() -> str:
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


@dataclass(frozen=True)
class Event:
    t_utc: str
    kind: str
    detail: str


MAX_JOURNAL_BYTES = 256 * 2**20  # far above any campaign's journal (the knee's: about 100 kB)
_NOT_A_RECORD = (  # what reading a line that is not a record raises (damaged, foreign, nested too deep)
    json.JSONDecodeError,
    KeyError,
    TypeError,
    ValueError,
    AttributeError,
    RecursionError,
    OverflowError,
)
MAX_FIELD_CHARS = 4096  # a step id, an event's kind or time: far longer is not a record this code wrote


def _text(rec: dict[str, Any], key: str) -> str:
    value = rec[key]
    if not isinstance(value, str) or len(value) > MAX_FIELD_CHARS:
        raise TypeError(f"{key} is not a text")
    return value


def _unit_record(rec: dict[str, Any]) -> UnitRecord:
    """A unit record's fields with the types and forms this code writes (a file name in units/, 64 hex
    digits, a size in bytes): anything else is not a record (a hand-edited or foreign line)."""
    file, sha256, size = _text(rec, "file"), _text(rec, "sha256"), rec["size"]
    if not (
        file.endswith(".h5") and len(file) <= 255 and "/" not in file and "\\" not in file and file[0] != "."
    ):
        raise ValueError("not a unit file name")
    if len(sha256) != 64 or any(c not in "0123456789abcdef" for c in sha256):
        raise ValueError("not a sha256")
    if not isinstance(size, int) or isinstance(size, bool) or size < 0:
        raise TypeError("not a size")
    return UnitRecord(_text(rec, "step_id"), file, sha256, size)


def _unusable(path: Path) -> str:
    """Why the existing `path` cannot be this session's journal ("" if it can): not a regular file (a link
    to /dev/zero would be read for ever), or larger than MAX_JOURNAL_BYTES."""
    if path.is_symlink():
        return f"{path} is a symbolic link"
    if not path.is_file():
        return f"{path} is not a regular file"
    if path.stat().st_size > MAX_JOURNAL_BYTES:
        return f"{path} is larger than {MAX_JOURNAL_BYTES // 2**20} MB"
    return ""


@dataclass(frozen=True)
class JournalDamage:
    """What reading a journal without writing it finds (`inspect_journal`)."""

    records: int  # lines that are journal records
    damaged: tuple[int, ...]  # 1-based numbers of the other non-empty lines, the last line aside
    units: dict[str, UnitRecord]  # the complete units the records leave journaled, by step id


def inspect_journal(path: Path) -> JournalDamage:
    """Read the journal at `path` without repairing it: its records, and the lines before the last one (the
    only one a crash can tear) that are not records. `OSError` for a file that is not a regular file or is
    larger than MAX_JOURNAL_BYTES."""
    reason = _unusable(path)
    if reason:
        raise OSError(reason)
    lines = path.read_bytes().split(b"\n")
    while lines and not lines[-1].strip():
        lines.pop()
    records = 0
    damaged: list[int] = []
    probe = Journal.__new__(Journal)
    probe.units, probe.failed, probe.events = {}, {}, []
    for number, raw in enumerate(lines, start=1):
        if not raw.strip():
            continue
        try:
            probe._apply(json.loads(raw.decode("utf-8")))
            records += 1
        except _NOT_A_RECORD:
            if number < len(lines):
                damaged.append(number)
    return JournalDamage(records, tuple(damaged), probe.units)


class Journal:
    def __init__(self, path: Path) -> None:
        self.path = path
        self.units: dict[str, UnitRecord] = {}  # complete units: skipped on resume
        # kept in the archive (e.g. a failed check) but redone on resume
        self.failed: dict[str, UnitRecord] = {}
        self.events: list[Event] = []
        self.damaged_lines = 0  # lines read that are not records (the torn tail, cut off first, aside)
        refuse_link(path)  # appended to: never through a link (session/lock.py)
        if path.exists():
            reason = _unusable(path)
            if reason:
                raise InvalidInput(f"{path}: not this session's journal ({reason})")
            self._repair_torn_tail()
            self._read()

    def _repair_torn_tail(self) -> None:
        """A crash mid-append can leave a last line without its newline: cut it off (it never described a
        complete unit), so the next record starts on a line of its own instead of being glued to it."""
        data = self.path.read_bytes()  # read only: a journal that needs no repair is not opened for writing
        if not data or data.endswith(b"\n"):
            return
        with self.path.open("rb+") as f:
            keep = data.rfind(b"\n") + 1
            f.truncate(keep)
            f.flush()
            os.fsync(f.fileno())

    def _read(self) -> None:
        with self.path.open("r", encoding="utf-8", errors="replace") as f:
            for line in f:
                line = line.strip()
                if not line:
                    continue
                try:
                    rec = json.loads(line)
                    self._apply(rec)
                except _NOT_A_RECORD:
                    self.damaged_lines += 1  # damaged or foreign line: ignored, never a complete unit

    def _apply(self, rec: dict[str, Any]) -> None:
        kind = rec.get("record")
        if kind == "unit":
            record = _unit_record(rec)
            if rec.get("final", True):
                self.units[record.step_id] = record
                self.failed.pop(record.step_id, None)
            else:
                self.failed[record.step_id] = record
                self.units.pop(record.step_id, None)
        elif kind == "invalidate":
            step_id = _text(rec, "step_id")
            self.units.pop(step_id, None)
            self.failed.pop(step_id, None)
        elif kind == "event":
            detail = rec.get("detail", "")
            if not isinstance(detail, str):
                raise TypeError("detail is not a text")
            self.events.append(Event(_text(rec, "t_utc"), _text(rec, "kind"), detail))

    def _append(self, rec: dict[str, Any]) -> None:
        line = json.dumps(rec, sort_keys=True) + "\n"
        fd = open_nofollow(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT)
        try:
            os.write(fd, line.encode("utf-8"))
            os.fsync(fd)
        finally:
            os.close(fd)
        self._apply(rec)

    def unit_done(self, record: UnitRecord, *, final: bool = True) -> None:
        self._append(
            {
                "record": "unit",
                "final": final,
                "step_id": record.step_id,
                "file": record.file,
                "sha256": record.sha256,
                "size": record.size,
                "t_utc": utc_now(),
            }
        )

    def invalidate(self, step_id: str, why: str) -> None:
        self._append({"record": "invalidate", "step_id": step_id, "why": why, "t_utc": utc_now()})

    def event(self, kind: str, detail: str = "") -> Event:
        ev = Event(utc_now(), kind, detail)
        self._append({"record": "event", **asdict(ev)})
        return ev

    def ended_cleanly(self) -> bool:
        """Did the last run of the session end with a recorded stop (finished, interrupted, stopped)?"""
        for ev in reversed(self.events):
            if ev.kind in ("started", "resumed"):
                return False
            if ev.kind in ("finished", "interrupted", "stopped", "aborted"):
                return True
        return True
