"""What `--report`, `--export` and `--compare` may write into a session: never over its own files (a review
replaced a trial's unit, the journal, session.json and archive.h5 with HTML through `--output`, exit 0),
and an archive they assemble for an unfinished session never replaces the one a resume finished meanwhile
(the review froze an `--export` between its look for archive.h5 and the session lock)."""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path

import pytest

from protocol_runner import commands
from protocol_runner.cli import main
from protocol_runner.session import lock as lock_module
from protocol_runner.session.journal import Journal

from .conftest import copy_session


@pytest.mark.parametrize("target", ["unit", "journal.jsonl", "session.json", "archive.h5"])
@pytest.mark.parametrize("command", ["--report", "--compare"])
def test_output_over_a_session_file_is_refused(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str], target: str, command: str
) -> None:
    session = copy_session(reference_archive, tmp_path / "s")
    if target == "unit":
        record = next(iter(Journal(session / "journal.jsonl").units.values()))
        path = session / "units" / record.file
    else:
        path = session / target
    before = path.read_bytes()
    args = (
        [command, str(session)] + ([str(session)] if command == "--compare" else []) + ["--output", str(path)]
    )
    assert main(args) == 2
    err = capsys.readouterr().err
    assert f"--output {path}: exists and is not an HTML page" in err and "Traceback" not in err, err
    assert path.read_bytes() == before


def test_output_over_an_earlier_report_is_allowed(tmp_path: Path, reference_archive: Path) -> None:
    session = copy_session(reference_archive, tmp_path / "s")
    earlier = tmp_path / "look.html"
    earlier.write_text("<!DOCTYPE html>\n<html><body>OLD-REPORT-MARKER</body></html>\n")
    assert main(["--report", str(session), "--output", str(earlier)]) == 0
    assert "OLD-REPORT-MARKER" not in earlier.read_text()


def test_an_archive_a_resume_finished_meanwhile_is_not_replaced(
    tmp_path: Path, reference_archive: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    session = copy_session(reference_archive, tmp_path / "s")
    finished = (session / "archive.h5").read_bytes()
    (session / "archive.h5").unlink()
    real_lock = lock_module.session_lock

    @contextmanager
    def lock_after_a_resume(directory: Path):  # type: ignore[no-untyped-def]
        (directory / "archive.h5").write_bytes(finished)  # the resume ended just before the lock was taken
        with real_lock(directory):
            yield

    monkeypatch.setattr(lock_module, "session_lock", lock_after_a_resume)
    assert commands.export(session, tmp_path / "tables") == 0
    assert (session / "archive.h5").read_bytes() == finished
