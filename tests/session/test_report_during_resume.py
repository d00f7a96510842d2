"""`--report` and a run or `--resume` of the same session coordinate through the session lock, so that a
report is never older than the archive beside it: while a resume holds the session, `--report` is refused
(exit 2, naming the holder; the resume writes the report itself when it ends) and touches nothing; once
the resume has ended, `--report` renders from the finished archive. Before, a `--report` running while a
resume finished could leave a report saying "incomplete" beside the complete archive, which a later
resume then refused to rewrite (the session looked complete)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from protocol_runner.cli import main
from protocol_runner.session.lock import session_lock

from .conftest import copy_session


def test_report_is_refused_while_the_session_is_held_and_renders_after(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = copy_session(reference_archive, tmp_path / "s")
    report = session / "report.html"
    before = (report.read_bytes(), report.stat().st_mtime_ns)
    with session_lock(session):  # a resume of the session is running
        for target in (session, session / "archive.h5"):
            assert main(["--report", str(target)]) == 2
            err = capsys.readouterr().err
            assert "in use by another run-protocol" in err and f"pid {os.getpid()}" in err, err
            assert (report.read_bytes(), report.stat().st_mtime_ns) == before
    assert main(["--report", str(session)]) == 0  # the resume has ended: rendered from its archive
    assert report.stat().st_mtime_ns != before[1]


def test_a_resume_is_refused_while_a_report_holds_the_session(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = copy_session(reference_archive, tmp_path / "s")
    (session / "archive.h5").unlink()
    (session / "report.html").unlink()
    journal = (session / "journal.jsonl").read_bytes()
    with session_lock(session):  # a --report of the session is rendering
        assert main(["--resume", str(session), "--yes"]) == 2
    assert "in use by another run-protocol" in capsys.readouterr().err
    assert (session / "journal.jsonl").read_bytes() == journal
    assert not (session / "archive.h5").exists()


def test_a_report_of_an_archive_outside_any_session_needs_no_lock(
    tmp_path: Path, reference_archive: Path
) -> None:
    alone = tmp_path / "alone.h5"
    alone.write_bytes(reference_archive.read_bytes())
    assert main(["--report", str(alone), "--output", str(tmp_path / "alone.html")]) == 0
    assert not (tmp_path / ".lock").exists()
