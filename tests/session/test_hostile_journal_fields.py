"""Journal lines and session files with the right keys but the wrong types or forms are not records (a
review got tracebacks from `--resume`, `--report`, `--export` and `--verify` for each of these): the resume
refuses the damaged journal, saying so, and the read-only commands go on without the line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from protocol_runner.cli import main

from .conftest import copy_session


def _copy(reference_archive: Path, to: Path) -> Path:
    copy_session(reference_archive, to)
    (to / "archive.h5").unlink()  # the commands then read the journal and the units
    return to


def _unit_line(session: Path) -> dict[str, object]:
    lines = (session / "journal.jsonl").read_text(encoding="utf-8").splitlines()
    return next(json.loads(line) for line in lines if json.loads(line).get("record") == "unit")


BAD_FIELDS = {
    "step id a number": {"step_id": 5},
    "no file": {"file": None},
    "file a number": {"file": 7},
    "file 5000 characters": {"file": "x" * 4996 + ".h5"},
    "file outside units": {"file": "../archive.h5"},
    "size infinite": {"size": 1e999},
    "size a float": {"size": 12.5},
    "sha256 not hex": {"sha256": "z" * 64},
}


@pytest.mark.parametrize("name", list(BAD_FIELDS))
def test_a_unit_line_with_a_wrong_field_is_not_a_record(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str], name: str
) -> None:
    session = _copy(reference_archive, tmp_path / "s")
    journal = session / "journal.jsonl"
    lines = journal.read_text(encoding="utf-8").splitlines()
    bad = {**_unit_line(session), **BAD_FIELDS[name]}
    text = json.dumps(bad).replace("Infinity", "1e999")  # as a hand edit would write it
    journal.write_text("\n".join([lines[0], text, *lines[1:]]) + "\n", encoding="utf-8")

    assert main(["--resume", str(session), "--yes"]) == 2
    err = capsys.readouterr().err
    assert "line 2 is not a journal record" in err and "Traceback" not in err, err
    assert main(["--verify", str(session)]) in (0, 1)
    assert main(["--export", str(session), "--output", str(tmp_path / "t")]) == 0
    assert "Traceback" not in capsys.readouterr().err


def test_a_seed_of_thousands_of_digits_is_a_damaged_session_file(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = _copy(reference_archive, tmp_path / "s")
    info = session / "session.json"
    info.write_text(info.read_text().replace('"seed": 7', '"seed": ' + "9" * 5001), encoding="utf-8")
    assert main(["--resume", str(session), "--yes"]) == 2
    err = capsys.readouterr().err
    assert "damaged session file (a number too long to read)" in err and "Traceback" not in err, err


def test_a_seed_edited_in_session_json_is_refused_unless_forced_and_then_recorded(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The review changed the seed 7 -> 8 by hand: the resume went on silently, and the archive said seed 8
    of trials the simulator had recorded with seed 7."""
    session = _copy(reference_archive, tmp_path / "s")
    journal = session / "journal.jsonl"
    lines = journal.read_text(encoding="utf-8").splitlines()
    kept = [line for line in lines if '"step_id": "fit:' not in line]  # a step left to do
    journal.write_text("\n".join(kept) + "\n", encoding="utf-8")
    info = session / "session.json"
    info.write_text(info.read_text().replace('"seed": 7', '"seed": 8'), encoding="utf-8")
    assert main(["--resume", str(session), "--yes"]) == 2
    err = capsys.readouterr().err
    assert "dry-run, seed 8, but the session began as dry-run, seed 7" in err and "Traceback" not in err, err
    assert main(["--resume", str(session), "--yes", "--force"]) == 0
    events = [json.loads(line) for line in journal.read_text(encoding="utf-8").splitlines()]
    assert any(
        e.get("kind") == "operator_override"
        and "although the session began as dry-run, seed 7" in e["detail"]
        for e in events
    )


def test_a_unit_that_no_longer_matches_its_journal_is_kept_aside_not_overwritten(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The review duplicated a journal line with another sha256: the resume redid the trial and wrote the
    new recording over the intact unit file. Whatever is wrong (the file or the journal), the file is kept."""
    session = _copy(reference_archive, tmp_path / "s")
    journal = session / "journal.jsonl"
    unit = _unit_line(session)
    original = (session / "units" / str(unit["file"])).read_bytes()
    with journal.open("a", encoding="utf-8") as f:
        f.write(json.dumps({**unit, "sha256": "0" * 64}) + "\n")  # a hand edit: the same step, another digest
    assert main(["--resume", str(session), "--yes"]) == 0, capsys.readouterr().err
    kept = session / "units" / f"{unit['file']}.replaced-1"
    assert kept.read_bytes() == original
    assert f"(the file is kept as {kept.name})" in capsys.readouterr().err
    assert (session / "units" / str(unit["file"])).is_file()  # recorded again
