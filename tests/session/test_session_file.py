"""What a resume trusts: session.json is checked field by field, and every
file the protocol references is hashed at creation and checked on resume (a change is refused, naming the
file, unless accepted with --force, which the archive records)."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import pytest

from protocol_runner.archive.units import sha256_of
from protocol_runner.cli import main
from protocol_runner.session.journal import Journal

from .conftest import copy_session


@pytest.mark.parametrize(
    ("edit", "named"),
    [
        (lambda d: d.update(seed=-5), "'seed'"),
        (lambda d: d.update(seed=True), "'seed'"),
        (lambda d: d.update(mode="banana"), "'mode'"),
        (lambda d: d.update(protocol_file="../../../etc/passwd"), "'protocol_file'"),
        (lambda d: d.update(only=["12"]), "'only'"),
        (lambda d: d.pop("protocol_sha256"), "'protocol_sha256'"),
        (lambda d: d.update(protocol_sha256=None), "'protocol_sha256'"),
        (lambda d: d.update(realtime="yes"), "'realtime'"),
        (lambda d: d.update(colour="blue"), "'colour'"),
        (lambda d: d.update(files_sha256={"../../x.csv": "0" * 64}), "'files_sha256'"),
    ],
)
def test_damaged_session_file_is_refused_naming_the_field(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str], edit, named: str
) -> None:  # type: ignore[no-untyped-def]
    session = copy_session(reference_archive, tmp_path / "s")
    path = session / "session.json"
    d = json.loads(path.read_text())
    edit(d)
    path.write_text(json.dumps(d))
    before = (session / "archive.h5").read_bytes()
    assert main(["--resume", str(session), "--yes"]) == 2
    err = capsys.readouterr().err
    assert named in err and "session.json" in err and "Traceback" not in err
    assert (session / "archive.h5").read_bytes() == before  # nothing touched


@pytest.mark.parametrize("text", ["", "[1, 2]", '{"seed": 1', "\udcff".encode("utf-8", "surrogatepass")])
def test_unreadable_session_file_is_refused(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str], text: str | bytes
) -> None:
    session = copy_session(reference_archive, tmp_path / "s")
    path = session / "session.json"
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    assert main(["--resume", str(session), "--yes"]) == 2
    err = capsys.readouterr().err
    assert "damaged session file" in err and "Traceback" not in err


def test_referenced_files_are_hashed_into_the_session_and_the_archive(reference_archive: Path) -> None:
    session = reference_archive.parent
    recorded = json.loads((session / "session.json").read_text())["files_sha256"]
    assert any(rel.startswith("calibration/") for rel in recorded)
    assert any(rel.startswith("trajectories/") for rel in recorded)
    for rel, digest in recorded.items():
        assert sha256_of(session / "protocol" / rel) == digest
    with h5py.File(reference_archive, "r") as f:
        events = [json.loads(e) for e in f["session/events"].asstr()[:]]
    archived = [json.loads(e["detail"]) for e in events if e["kind"] == "referenced_files"]
    assert archived == [recorded]


def test_changed_calibration_table_is_refused_unless_forced(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = copy_session(reference_archive, tmp_path / "s")
    (session / "archive.h5").unlink()  # an unfinished session: a resume has work to do
    table = session / "protocol" / "calibration" / "knee_angle.csv"
    table.write_text(table.read_text() + "\n")
    assert main(["--resume", str(session), "--yes"]) == 2
    err = capsys.readouterr().err
    assert "calibration/knee_angle.csv (changed)" in err and "--force" in err
    assert not (session / "archive.h5").exists()

    assert main(["--resume", str(session), "--yes", "--force"]) == 0
    overrides = [e.detail for e in Journal(session / "journal.jsonl").events if e.kind == "operator_override"]
    assert any("calibration/knee_angle.csv" in d for d in overrides)
    with h5py.File(session / "archive.h5", "r") as f:
        assert any("calibration/knee_angle.csv" in e for e in f["session/events"].asstr()[:])


def test_missing_trajectory_file_is_named(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = copy_session(reference_archive, tmp_path / "s")
    victim = next((session / "protocol" / "trajectories").iterdir())
    victim.unlink()
    assert main(["--resume", str(session), "--yes"]) == 2
    assert f"trajectories/{victim.name} (missing)" in capsys.readouterr().err
