"""A full disk (ENOSPC from the writer) inside a unit write, consolidation, report writing and session
creation: one clear message and exit 130, the joint parked, no partial file, every complete unit kept, and
once space is freed the session resumes to an archive identical to an uninterrupted run (
finding 4). The last test fills a real (tmpfs) file system where the machine allows mounting one."""

from __future__ import annotations

import errno
import io
import pathlib
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import h5py
import pytest

from protocol_runner.archive import consolidate as consolidate_module
from protocol_runner.cli import main
from protocol_runner.hardware.rig import Rig
from protocol_runner.report import predictions as predictions_module
from protocol_runner.session import setup as session_setup
from protocol_runner.session.journal import Journal

from .conftest import ONLY, SEED, assert_same_data

RUN = ["knee_phase1.yaml", "--dry-run", "--only", ",".join(map(str, ONLY)), "--seed", str(SEED)]
STEPS = 12  # steps of --only 12 that write a unit (all but the report)


def enospc(*_: object, **__: object) -> Any:
    raise OSError(errno.ENOSPC, "No space left on device")


def after(n: int, real: Callable[..., Any]) -> Callable[..., Any]:
    """`real`, except that its n-th and later calls fail with ENOSPC (the disk filled up meanwhile)."""
    calls = {"n": 0}

    def call(*args: Any, **kwargs: Any) -> Any:
        calls["n"] += 1
        if calls["n"] >= n:
            enospc()
        return real(*args, **kwargs)

    return call


@pytest.fixture
def parks(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Where the rig was parked, in order."""
    seen: list[str] = []
    real = Rig.park

    def park(self: Rig, **kwargs: Any) -> Any:
        seen.append(str(kwargs.get("where", "park")))
        return real(self, **kwargs)

    monkeypatch.setattr(Rig, "park", park)
    return seen


def stopped_cleanly(code: int, err: str, session: Path) -> None:
    assert code == 130, err
    assert "Traceback" not in err and "Logging error" not in err, err
    messages = [line for line in err.splitlines() if line.startswith("run-protocol:")]
    assert len(messages) == 1 and "disk full" in messages[0], err
    assert not [p for p in session.rglob("*") if ".partial" in p.name]


def resume_matches(session: Path, reference: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--resume", str(session), "--yes"]) == 0, capsys.readouterr().err
    assert_same_data(reference, session / "archive.h5")
    assert (session / "report.html").is_file()


def test_enospc_inside_a_unit_write(
    tmp_path: Path,
    reference_archive: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    parks: list[str],
) -> None:
    session = tmp_path / "s"
    # the 38th dataset: inside the third trial's unit, after some of its datasets were written
    monkeypatch.setattr(h5py.Group, "create_dataset", after(38, h5py.Group.create_dataset))
    code = main([*RUN, "--session", str(session)])
    err = capsys.readouterr().err
    stopped_cleanly(code, err, session)
    assert "--resume" in err
    kept = Journal(session / "journal.jsonl").units
    assert 2 <= len(kept) < STEPS
    assert parks[-1] == "park after disk full"
    monkeypatch.undo()  # space is freed
    resume_matches(session, reference_archive, capsys)


def test_enospc_while_journaling_a_finished_unit(
    tmp_path: Path,
    reference_archive: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    parks: list[str],
) -> None:
    """The unit is on disk but could not be journaled: it counts as not done, and is redone on resume."""
    session = tmp_path / "s"
    monkeypatch.setattr(Journal, "unit_done", after(4, Journal.unit_done))
    code = main([*RUN, "--session", str(session)])
    err = capsys.readouterr().err
    stopped_cleanly(code, err, session)
    assert "--resume" in err and len(Journal(session / "journal.jsonl").units) == 3
    assert parks[-1] == "park after disk full"
    monkeypatch.undo()
    resume_matches(session, reference_archive, capsys)


def test_enospc_while_consolidating(
    tmp_path: Path,
    reference_archive: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    parks: list[str],
) -> None:
    session = tmp_path / "s"
    monkeypatch.setattr(consolidate_module, "put_text", enospc)  # after every unit was merged
    code = main([*RUN, "--session", str(session)])
    err = capsys.readouterr().err
    stopped_cleanly(code, err, session)
    assert f"disk full while writing {session / 'archive.h5'}" in err and "--resume" in err
    assert not (session / "archive.h5").exists()
    assert len(Journal(session / "journal.jsonl").units) == STEPS  # every complete unit kept
    assert parks[-1] == "park after disk full"
    monkeypatch.undo()
    resume_matches(session, reference_archive, capsys)


def test_enospc_while_writing_the_report(
    tmp_path: Path,
    reference_archive: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    parks: list[str],
) -> None:
    session = tmp_path / "s"
    real_open = pathlib.Path.open

    def open_(self: Path, mode: str = "r", *args: Any, **kwargs: Any) -> Any:
        fh = real_open(self, mode, *args, **kwargs)
        if ("w" in mode or "x" in mode) and "report.html" in self.name:  # x: created new
            return _FillsUp(fh, room=20_000)
        return fh

    monkeypatch.setattr(pathlib.Path, "open", open_)
    code = main([*RUN, "--session", str(session)])
    err = capsys.readouterr().err
    stopped_cleanly(code, err, session)
    assert f"disk full while writing {session / 'report.html'} (the archive is complete)" in err
    assert not (session / "report.html").exists()
    with h5py.File(session / "archive.h5", "r") as f:
        assert f.attrs["status"] == "complete"
    assert main(["--verify", str(session / "archive.h5")]) == 0
    assert parks[-1] == "park after disk full"
    monkeypatch.undo()
    resume_matches(session, reference_archive, capsys)


def test_enospc_while_recording_the_predictions(
    tmp_path: Path,
    reference_archive: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    parks: list[str],
) -> None:
    """The predictions are recorded after the figures are drawn and before the page is written: a full disk
    then names the predictions, and no report is left (it would show what the archive does not hold)."""
    session = tmp_path / "s"
    monkeypatch.setattr(predictions_module, "record_predictions", enospc)
    code = main([*RUN, "--session", str(session)])
    err = capsys.readouterr().err
    stopped_cleanly(code, err, session)
    assert f"disk full while writing the predictions into {session / 'archive.h5'}" in err
    assert not (session / "report.html").exists()
    assert parks[-1] == "park after disk full"
    monkeypatch.undo()
    resume_matches(session, reference_archive, capsys)


class _FillsUp:
    """A text file on a disk with `room` characters left."""

    def __init__(self, fh: io.TextIOWrapper, room: int) -> None:
        self._fh, self._room = fh, room

    def write(self, text: str) -> int:
        if len(text) > self._room:
            self._fh.write(text[: self._room])
            self._fh.flush()
            enospc()
        self._room -= len(text)
        return self._fh.write(text)

    def __enter__(self) -> _FillsUp:
        return self

    def __exit__(self, *exc: object) -> None:
        self._fh.close()


@pytest.mark.parametrize("existed", [False, True], ids=["new folder", "empty folder given"])
def test_enospc_while_creating_the_session(
    tmp_path: Path,
    reference_archive: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    existed: bool,
) -> None:
    session = tmp_path / "s"
    if existed:
        session.mkdir()
    monkeypatch.setattr(session_setup.shutil, "copy2", after(3, shutil.copy2))  # the third referenced file
    code = main([*RUN, "--session", str(session)])
    err = capsys.readouterr().err
    assert code == 130 and "Traceback" not in err
    assert "disk full while creating the session" in err and "nothing was recorded" in err
    assert session.is_dir() == existed and (not existed or not any(session.iterdir()))  # nothing half-made
    monkeypatch.undo()
    assert main([*RUN, "--session", str(session)]) == 0  # the same command, once space is freed
    assert_same_data(reference_archive, session / "archive.h5")


def test_another_write_error_while_creating_the_session_is_exit_2_and_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def denied(src: object, dst: object, **_: object) -> None:
        raise PermissionError(errno.EACCES, "Permission denied", str(dst))

    monkeypatch.setattr(session_setup.shutil, "copy2", denied)
    session = tmp_path / "s"
    code = main([*RUN, "--session", str(session)])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    assert f"--session {session}: cannot create the session (Permission denied: {session}" in err
    assert not session.exists()


def _can_mount_tmpfs(where: Path) -> bool:
    if shutil.which("unshare") is None or not sys.platform.startswith("linux"):
        return False
    where.mkdir(exist_ok=True)
    probe = subprocess.run(
        ["unshare", "-Urm", "sh", "-c", f"mount -t tmpfs -o size=1m tmpfs {where}"],
        capture_output=True,
        timeout=30,
    )
    return probe.returncode == 0


def _footprint_kb(files: list[Path]) -> float:
    return sum(-(-p.stat().st_size // 4096) * 4 for p in files if p.is_file())  # tmpfs: whole pages


@pytest.mark.parametrize(
    ("phase", "expected"),
    [
        ("unit", "while saving"),
        ("early unit", "while saving"),  # HDF5 fails closing a unit: a RuntimeError, then a crash at exit
        ("late unit", "while saving"),
        ("archive", "archive.h5"),
        ("report", "report.html"),
    ],
)
def test_a_really_full_disk_then_resume_gives_the_same_archive(
    tmp_path: Path, reference_archive: Path, phase: str, expected: str
) -> None:
    """The file system's size is chosen from the uninterrupted run's files so that it fills up in the
    middle of the units, of the archive, or of the report. Sized for the archive, it may also fill while a
    worker writes one of the last units: that unit's write then fails, and says so, as any unit's does
    (archive/h5_write_errors.py)."""
    ref = reference_archive.parent
    units = _footprint_kb(list((ref / "units").iterdir()))
    archive = _footprint_kb([ref / "archive.h5"])
    report = _footprint_kb([ref / "report.html"])
    rest = _footprint_kb(
        [p for p in ref.rglob("*") if "units" not in p.parts and p.suffix not in (".h5", ".html")]
    )
    size_kb = int(
        rest
        + 8
        + {
            "unit": units / 2,
            "early unit": units / 4,
            "late unit": units * 3 / 4,
            "archive": units + archive / 2,
            "report": units + archive + report / 2,
        }[phase]
    )
    mnt = tmp_path / "mnt"
    if not _can_mount_tmpfs(mnt):
        pytest.skip("cannot mount a small tmpfs here (needs user and mount namespaces)")
    session = mnt / "s"
    py = f"{sys.executable} -m protocol_runner.cli"
    script = f"""
        mount -t tmpfs -o size={size_kb}k tmpfs {mnt} || exit 99
        {py} {" ".join(RUN)} --session {session} 2> {tmp_path}/err1; echo $? > {tmp_path}/code1
        find {session} -name '*.partial' > {tmp_path}/partials
        mount -o remount,size=64m {mnt}
        {py} --resume {session} 2> {tmp_path}/err2; echo $? > {tmp_path}/code2
        cp {session}/archive.h5 {tmp_path}/archive.h5
    """
    done = subprocess.run(["unshare", "-Urm", "sh", "-c", script], timeout=600, cwd=Path.cwd())
    assert done.returncode == 0
    err1 = (tmp_path / "err1").read_text()
    assert (tmp_path / "code1").read_text().strip() == "130", err1
    assert "Traceback" not in err1 and "Logging error" not in err1, err1
    message = [line for line in err1.splitlines() if line.startswith("run-protocol:")]
    assert len(message) == 1 and message[0].startswith("run-protocol: disk full")
    assert expected in message[0] or (phase == "archive" and "while saving" in message[0]), message[0]
    assert (tmp_path / "partials").read_text() == ""
    assert (tmp_path / "code2").read_text().strip() == "0", (tmp_path / "err2").read_text()
    assert_same_data(reference_archive, tmp_path / "archive.h5")


def test_hdf5s_runtime_error_of_a_full_disk_is_a_full_disk() -> None:
    from protocol_runner.archive.diskfull import is_disk_full

    closing = RuntimeError(
        "Disable slist on flush dest failure failed (file write failed: time = Fri Dec  4 18:59:01 2026, "
        "filename = 'units/trial__k16__on__1.h5.partial', file descriptor = 7, errno = 28, error message = "
        "'No space left on device', buf = 0x55d0, total write size = 4096, bytes this sub-write = 4096)"
    )
    assert is_disk_full(closing)
    assert is_disk_full(RuntimeError("H5Fclose failed (errno = 122, error message = 'Disk quota exceeded')"))
    assert not is_disk_full(RuntimeError("Unable to synchronously create dataset (name already exists)"))
    assert not is_disk_full(RuntimeError("errno = 2, error message = 'No such file or directory'"))


def test_enospc_during_export_mat_is_a_full_disk_with_only_complete_files_left(
    tmp_path: Path,
    reference_archive: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    from protocol_runner.archive import export

    out = tmp_path / "mat"
    monkeypatch.setattr(export, "savemat", after(2, export.savemat))  # the second file meets a full disk
    code = main(["--report", str(reference_archive), "--export-mat", str(out)])
    err = capsys.readouterr().err
    assert code == 130, err
    assert "run-protocol: disk full while writing" in err and "--export-mat" in err and "Traceback" not in err
    left = sorted(p.name for p in out.iterdir())
    assert len(left) == 1 and left[0].endswith(".mat")  # the first, complete; no partial file
