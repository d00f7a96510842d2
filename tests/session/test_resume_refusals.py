"""Resume never silently redoes or rewrites recorded work: a finished session is left as
it is, a missing journal is refused (unless --force, recorded), --seed/--only cannot change a session;
progress counts every step including the report; a DT9814 protocol is refused saying what to do."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from protocol_runner.cli import main
from protocol_runner.protocol.loader import find_protocol
from protocol_runner.resources import packaged_rigs_dir
from protocol_runner.session.journal import Journal

from .conftest import ONLY, SEED, copy_session


def snapshot(session: Path) -> dict[str, tuple[bytes, int]]:
    return {
        str(p.relative_to(session)): (p.read_bytes(), p.stat().st_mtime_ns)
        for p in sorted(session.rglob("*"))
        if p.is_file() and p.name != ".lock"
    }


def test_resuming_a_finished_session_changes_nothing(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = copy_session(reference_archive, tmp_path / "done")
    before = snapshot(session)
    assert main(["--resume", str(session), "--yes"]) == 0
    assert "is complete" in capsys.readouterr().err
    assert snapshot(session) == before  # archive, report, journal and log untouched


def test_deleted_journal_is_refused_not_silently_redone(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = copy_session(reference_archive, tmp_path / "nojournal")
    (session / "journal.jsonl").unlink()
    (session / "archive.h5").unlink()
    units = snapshot(session / "units")
    assert main(["--resume", str(session), "--yes"]) == 2
    err = capsys.readouterr().err
    assert "journal.jsonl" in err and "--force" in err and "Traceback" not in err
    assert snapshot(session / "units") == units

    assert main(["--resume", str(session), "--yes", "--force"]) == 0  # every step redone, and recorded
    journal = Journal(session / "journal.jsonl")
    assert any(
        "journal.jsonl was missing" in e.detail for e in journal.events if e.kind == "operator_override"
    )


def _emptied(path: Path) -> None:
    path.write_bytes(b"")


def _zeroed(path: Path) -> None:  # a power cut on some file systems: the blocks read back as zeros
    path.write_bytes(b"\0" * path.stat().st_size)


def _garbled(path: Path) -> None:  # a line in the middle overwritten: no longer a record
    lines = path.read_bytes().split(b"\n")
    lines[len(lines) // 2] = b"\x00\x17 #### overwritten ####"
    path.write_bytes(b"\n".join(lines))


@pytest.mark.parametrize("damage", [_emptied, _zeroed, _garbled], ids=["emptied", "zeroed", "garbled"])
def test_a_damaged_journal_is_refused_not_silently_redone(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str], damage
) -> None:
    session = copy_session(reference_archive, tmp_path / "damaged")
    (session / "archive.h5").unlink()
    damage(session / "journal.jsonl")
    before = snapshot(session)
    assert main(["--resume", str(session), "--yes"]) == 2
    err = capsys.readouterr().err
    assert "journal.jsonl" in err and "--force" in err and "Traceback" not in err
    assert ("holds no journal record" in err) == (damage is not _garbled)
    assert ("is not a journal record" in err or "are not a journal record" in err) == (damage is _garbled)
    assert snapshot(session) == before  # refused before anything is read for the resume: nothing repaired

    assert main(["--resume", str(session), "--yes", "--force"]) == 0  # redone, and recorded
    overrides = [e.detail for e in Journal(session / "journal.jsonl").events if e.kind == "operator_override"]
    wanted = (
        "damaged line(s), ignored" if damage is _garbled else "journal.jsonl was missing or held no record"
    )
    assert any(wanted in detail for detail in overrides), overrides


def test_a_torn_last_line_is_what_a_crash_leaves_and_is_resumed(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = copy_session(reference_archive, tmp_path / "torn")
    (session / "archive.h5").unlink()
    journal = session / "journal.jsonl"
    journal.write_bytes(journal.read_bytes() + b'{"record": "unit", "step_id": "tri')  # cut mid-append
    assert main(["--resume", str(session), "--yes"]) == 0
    assert "already complete" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["--seed", str(SEED + 1)], "--seed"),
        (["--only", "13"], "--only"),
        (["--only", f"{ONLY[0]},13"], "--only"),
    ],
)
def test_resume_refuses_a_different_seed_or_only(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str], args: list[str], named: str
) -> None:
    session = copy_session(reference_archive, tmp_path / "s")
    assert main(["--resume", str(session), "--yes", *args]) == 2
    err = capsys.readouterr().err
    assert named in err and "new session" in err and "Traceback" not in err


def test_resume_accepts_the_sessions_own_seed_and_only(tmp_path: Path, reference_archive: Path) -> None:
    session = copy_session(reference_archive, tmp_path / "s")
    only = ",".join(map(str, ONLY))
    assert main(["--resume", str(session), "--yes", "--seed", str(SEED), "--only", only]) == 0


def test_resume_with_a_protocol_argument_is_refused(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = copy_session(reference_archive, tmp_path / "s")
    assert main(["knee_phase1.yaml", "--resume", str(session)]) == 2
    assert "drop PROTOCOL" in capsys.readouterr().err


def test_progress_counts_the_report_step(reference_archive: Path) -> None:
    log = (reference_archive.parent / "session.log").read_text()
    counts = [line.split("[", 1)[1].split("]", 1)[0] for line in log.splitlines() if "] report:" in line]
    assert len(counts) == 1
    done, total = counts[0].split("/")
    assert done == total


def test_dt9814_protocol_is_refused_naming_the_file_line_and_key_that_choose_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # knee_phase1 chooses the DT9814 itself: rig_overrides.input_board
    session = tmp_path / "hw"
    protocol = find_protocol("knee_phase1.yaml")
    line = 1 + protocol.read_text().splitlines().index(
        "  input_board: dt9814                # DT9814-10V, 12 bit, +-10 V (§2.3)"
    )
    assert main(["knee_phase1.yaml", "--session", str(session)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"run-protocol: {protocol} line {line}: rig_overrides.input_board is dt9814."), err
    assert "rig_overrides.input_board: usb1608fs" in err and "USB-1608FS-Plus" in err and "--dry-run" in err
    assert not session.exists() and "Traceback" not in err


def test_dt9814_of_the_rig_file_is_refused_naming_the_rig_file_line_and_key(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # elbow_example takes the rig file's input board: rigs/rsst.yaml `input_board: dt9814`
    session = tmp_path / "hw"
    rig = packaged_rigs_dir() / "rsst.yaml"
    line = 1 + next(
        i for i, t in enumerate(rig.read_text().splitlines()) if t.startswith("input_board: dt9814")
    )
    assert main(["elbow_example.yaml", "--session", str(session)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"run-protocol: {rig} line {line}: input_board is dt9814."), err
    assert "rig_overrides: {input_board: usb1608fs}" in err
    assert not session.exists() and "Traceback" not in err


def test_verify_names_a_journaled_unit_whose_file_is_gone(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = copy_session(reference_archive, tmp_path / "lost")
    assert main(["--verify", str(session)]) == 0
    capsys.readouterr()
    record = Journal(session / "journal.jsonl").units
    step_id, gone = next((k, r) for k, r in sorted(record.items()) if k.startswith("trial:"))
    (session / "units" / gone.file).unlink()
    assert main(["--verify", str(session)]) == 2
    err = capsys.readouterr().err
    assert f"{gone.file}: journaled as the complete unit of {step_id} but missing" in err, err
    assert err.count("journaled as the complete unit") == 1


def test_a_journal_that_is_not_a_file_is_refused_without_reading_it(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = copy_session(reference_archive, tmp_path / "devzero")
    (session / "archive.h5").unlink()
    (session / "journal.jsonl").unlink()
    (session / "journal.jsonl").symlink_to("/dev/zero")  # endless: read, it would fill the memory
    assert main(["--resume", str(session), "--yes"]) == 2
    err = capsys.readouterr().err
    assert "journal.jsonl" in err and "symbolic link" in err and "Traceback" not in err


def test_an_archive_that_is_a_directory_is_one_line_not_a_traceback(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = copy_session(reference_archive, tmp_path / "dir")
    (session / "archive.h5").unlink()
    (session / "archive.h5").mkdir()
    for command in (["--report", str(session)], ["--export", str(session), "--output", str(tmp_path / "t")]):
        assert main(command) == 2
        err = capsys.readouterr().err
        assert err.startswith("run-protocol: ") and "Traceback" not in err
        assert len(err.strip().splitlines()) == 1, err


def test_a_read_only_session_is_said_so_and_a_finished_one_resumes_to_nothing(
    tmp_path: Path, reference_archive: Path
) -> None:
    import shutil as sh
    import subprocess
    import sys

    session = copy_session(reference_archive, tmp_path / "ro")
    if sh.which("unshare") is None:
        pytest.skip("no unshare: cannot make a read-only bind mount here")
    cli = f"{sys.executable} -m protocol_runner.cli"
    script = f"""
        mount --bind {session} {session} && mount -o remount,bind,ro {session} || exit 99
        {cli} --resume {session} --yes > {tmp_path}/out1 2> {tmp_path}/err1; echo $? > {tmp_path}/code1
        {cli} --report {session} 2> {tmp_path}/err2; echo $? > {tmp_path}/code2
        {cli} --export {session} 2> {tmp_path}/err3; echo $? > {tmp_path}/code3
    """
    done = subprocess.run(["unshare", "-Urm", "sh", "-c", script], timeout=300, cwd=tmp_path)
    if done.returncode == 99 or not (tmp_path / "code1").exists():
        pytest.skip("cannot make a read-only bind mount here (needs user and mount namespaces)")
    assert (tmp_path / "code1").read_text().strip() == "0"  # finished: nothing to write, nothing written
    assert "is complete" in (tmp_path / "err1").read_text()
    for k in (2, 3):
        err = (tmp_path / f"err{k}").read_text()
        assert (tmp_path / f"code{k}").read_text().strip() == "2", err
        assert "Read-only file system" in err and "writable place" in err and "Traceback" not in err


def test_what_was_computed_from_a_redone_recording_is_redone_with_it(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A damaged brace-on unit is recorded again on resume; on the rig that is a new recording, so its
    brace-off twin (which follows its measured output), the processing and the fit made from the old one
    are made again too, not kept beside it."""
    from .conftest import assert_same_data

    session = copy_session(reference_archive, tmp_path / "redo")
    (session / "archive.h5").unlink()
    journal = Journal(session / "journal.jsonl")
    on_id = next(k for k in journal.units if k.startswith("trial:") and ":on:" in k)
    unit = session / "units" / journal.units[on_id].file
    data = bytearray(unit.read_bytes())
    data[len(data) // 2] ^= 0xFF  # one flipped byte: its sha256 no longer matches the journal
    unit.write_bytes(bytes(data))
    key = on_id.split(":")[1]
    assert main(["--resume", str(session), "--yes"]) == 0
    err = capsys.readouterr().err
    invalidated = {}
    for line in (session / "journal.jsonl").read_text().splitlines():
        rec = json.loads(line)
        if rec.get("record") == "invalidate":
            invalidated[rec["step_id"]] = rec["why"]
    twin = on_id.replace(":on:", ":off:")
    assert invalidated[on_id] == "unit file missing, truncated or corrupt"
    for derived in (twin, f"process:{key}", f"fit:{key}"):
        assert invalidated[derived] == f"derived from {on_id}, which is redone", invalidated
        assert f"{derived}: derived from {on_id}, which is redone" in err
    assert_same_data(reference_archive, session / "archive.h5")  # the simulator records the same again


@pytest.mark.parametrize("how", ["consolidated by --report", "truncated"])
def test_a_finished_session_whose_archive_is_not_its_finished_one_is_assembled_again(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str], how: str
) -> None:
    import h5py

    from .conftest import assert_same_data

    session = copy_session(reference_archive, tmp_path / "again")
    archive = session / "archive.h5"
    if how == "truncated":
        with archive.open("r+b") as f:
            f.truncate(archive.stat().st_size // 2)
    else:  # --report on a session without its archive consolidates one from the units: "incomplete"
        archive.unlink()
        assert main(["--report", str(session), "--output", str(tmp_path / "look.html")]) == 0
        with h5py.File(archive, "r") as f:
            assert f.attrs["status"] == "incomplete"
    capsys.readouterr()
    assert main(["--resume", str(session), "--yes"]) == 0
    out = capsys.readouterr().out
    assert "done: 1 step run, 12 already complete;" in out  # nothing redone: the archive and report again
    with h5py.File(archive, "r") as f:
        assert f.attrs["status"] == "complete" and "expectations" in f
    assert_same_data(reference_archive, archive)


def test_a_hand_edited_only_is_refused_as_the_journal_disagrees(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = copy_session(reference_archive, tmp_path / "edited")
    (session / "archive.h5").unlink()
    info = json.loads((session / "session.json").read_text())
    info["only"] = [k + 1 for k in info["only"]]  # another configuration than the one that ran
    (session / "session.json").write_text(json.dumps(info))
    assert main(["--resume", str(session), "--yes"]) == 2
    err = capsys.readouterr().err
    assert "records finished steps the session's plan does not have" in err and "session.json" in err
    assert main(["--resume", str(session), "--yes", "--force"]) == 0
    overrides = [e.detail for e in Journal(session / "journal.jsonl").events if e.kind == "operator_override"]
    assert any("the journal records steps the plan does not have" in d for d in overrides), overrides


@pytest.mark.parametrize("what", ["a directory where a unit belongs", "units a link loop", "units a file"])
def test_a_unit_path_the_resume_could_not_save_to_is_refused_before_any_step_runs(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str], what: str
) -> None:
    """Before, a directory where a trial's unit belongs let the resume re-run the set's calibration check
    and the trial (on the rig, a run of the robot) and only then fail to save it, as an "internal error";
    `units` as a link loop was refused as "File exists" (a link is never followed: session/lock.py)."""
    session = copy_session(reference_archive, tmp_path / "s")
    (session / "archive.h5").unlink()
    journal = Journal(session / "journal.jsonl")
    trial = next(k for k in journal.units if k.startswith("trial:"))
    unit = session / "units" / journal.units[trial].file
    if what == "a directory where a unit belongs":
        unit.unlink()
        unit.mkdir()
        named = f"{unit}: is a directory, where the unit file of step {trial} belongs"
    elif what == "units a link loop":
        (session / "units").rename(session / "units.kept")
        (session / "units").symlink_to("units")
        named = f"{session / 'units'} is a symbolic link"
    else:
        shutil.rmtree(session / "units")
        (session / "units").write_text("not a directory\n")
        named = f"{session / 'units'}: is not a directory"
    before = (session / "journal.jsonl").read_bytes()
    assert main(["--resume", str(session), "--yes"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"run-protocol: {named}") and "Traceback" not in err, err
    assert len(err.strip().splitlines()) == 1, err
    assert (session / "journal.jsonl").read_bytes() == before  # nothing ran, nothing was journaled
    assert not (session / "archive.h5").exists()


def test_a_unit_that_cannot_be_moved_into_place_mid_run_is_said_so_not_called_an_internal_error(
    tmp_path: Path,
    reference_archive: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """A directory made where a unit belongs while the session runs: the rename of the finished unit onto it
    fails. The session stops saying which move failed (both paths), keeps what it finished, and resumes
    once the directory is gone, to the data of an uninterrupted run."""
    import os as os_module

    from protocol_runner.archive import units as units_module
    from protocol_runner.archive.units import unit_is_complete

    from .conftest import assert_same_data

    session = tmp_path / "s"
    real = os_module.replace
    moved = {"n": 0}

    def replace(src: object, dst: object) -> None:
        moved["n"] += 1
        if moved["n"] == 4:  # the fourth unit: a directory appeared where it belongs
            Path(str(dst)).mkdir()
            raise IsADirectoryError(21, "Is a directory", str(src), None, str(dst))
        real(src, dst)  # type: ignore[arg-type]

    monkeypatch.setattr(units_module.os, "replace", replace)
    code = main(["knee_phase1.yaml", "--dry-run", "--only", "12", "--seed", "7", "--session", str(session)])
    err = capsys.readouterr().err
    monkeypatch.undo()
    assert code == 2, err
    assert "internal error" not in err and "Traceback" not in err, err
    blocked = next(p for p in (session / "units").iterdir() if p.is_dir())
    assert f"run-protocol: cannot move {blocked}.partial to {blocked}: Is a directory" in err, err
    assert f"session stopped: cannot move {blocked}.partial to {blocked}" in err, err
    kept = Journal(session / "journal.jsonl").units
    assert 2 <= len(kept) < 12 and all(unit_is_complete(session / "units", r) for r in kept.values())
    assert main(["--resume", str(session), "--yes"]) == 2  # refused while the directory is there
    assert f"{blocked}: is a directory" in capsys.readouterr().err
    blocked.rmdir()
    assert main(["--resume", str(session), "--yes"]) == 0, capsys.readouterr().err
    assert_same_data(reference_archive, session / "archive.h5")
