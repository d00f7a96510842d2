"""The journal survives torn and foreign lines; a session directory is used by one process at a time."""

from __future__ import annotations

from pathlib import Path

import pytest

from protocol_runner.archive.units import UnitRecord
from protocol_runner.errors import InvalidInput
from protocol_runner.session.journal import Journal
from protocol_runner.session.lock import session_lock


def test_a_record_appended_after_a_torn_line_is_kept(tmp_path: Path) -> None:
    path = tmp_path / "journal.jsonl"
    j = Journal(path)
    j.unit_done(UnitRecord("trial:k01:on:1", "trial__k01__on__1.h5", "ab" * 32, 123))
    j.event("started", "dry-run")
    data = path.read_bytes()
    path.write_bytes(data[:-20])  # a crash in the middle of the last append
    again = Journal(path)
    assert path.read_bytes().endswith(b"\n") and again.damaged_lines == 0  # the torn tail is cut off
    assert "trial:k01:on:1" in again.units
    again.event("resumed")
    third = Journal(path)
    assert [e.kind for e in third.events] == ["resumed"]  # the torn "started" is gone, "resumed" is whole
    assert third.damaged_lines == 0


def test_foreign_lines_are_ignored_not_fatal(tmp_path: Path) -> None:
    path = tmp_path / "journal.jsonl"
    path.write_text(
        '{"record": "unit", "step_id": "x"}\n[1, 2]\n"text"\n{"record": "event", "t_utc": "t", "kind": "started"}\n'
    )
    j = Journal(path)
    assert j.units == {} and [e.kind for e in j.events] == ["started"] and j.damaged_lines == 3


def test_a_session_directory_is_locked_while_in_use(tmp_path: Path) -> None:
    with (
        session_lock(tmp_path),
        pytest.raises(InvalidInput, match="in use by another run-protocol"),
        session_lock(tmp_path),
    ):
        pass
    with session_lock(tmp_path):  # released when the holder is done
        pass
