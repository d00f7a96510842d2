"""Crash safety: SIGKILL at random points, resume, repeat; the final archive equals an uninterrupted run's.

Also SIGINT (exit 130, resumable, nothing lost), a truncated unit (detected and redone), a changed protocol
(refused unless --force), a full disk (clean stop, nothing lost) and a failing calibration check (exit 4).
"""

from __future__ import annotations

import errno
import json
import random
import signal
import time
from pathlib import Path

import h5py
import pytest

from protocol_runner.archive import units as units_module
from protocol_runner.archive.diskfull import DiskFull
from protocol_runner.commands import resume
from protocol_runner.errors import StoppedByCheck
from protocol_runner.session.journal import Journal

from .conftest import ONLY, SEED, assert_same_data, cli, run_dry


def journal_units(session: Path) -> int:
    """The units a running session has journaled as complete, read without writing (`Journal(path)` would
    cut a line the session is appending at that instant as a torn tail)."""
    path = session / "journal.jsonl"
    if not path.exists():
        return 0
    done: set[str] = set()
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines(keepends=True):
        if not line.endswith("\n"):
            continue  # being appended
        rec = json.loads(line)
        if rec.get("record") == "unit" and rec.get("final", True):
            done.add(rec["step_id"])
        elif rec.get("record") in ("unit", "invalidate"):  # a failed check's unit, or one to redo
            done.discard(rec["step_id"])
    return len(done)


def wait_for_units(proc, session: Path, n: int, timeout_s: float = 120.0) -> bool:  # type: ignore[no-untyped-def]
    """Wait until `n` units are journaled; False if the run finished first (exit 0) before that."""
    deadline = time.monotonic() + timeout_s
    while journal_units(session) < n:
        code = proc.poll()
        if code is not None:
            assert code == 0, proc.stderr()
            return False
        assert time.monotonic() < deadline, "the run made no progress"
        time.sleep(0.02)
    return True


def test_sigkill_at_random_points_then_resume_gives_identical_archive(
    tmp_path: Path, reference_archive: Path
) -> None:
    rng = random.Random(20071001)
    session = tmp_path / "killed"
    only = ",".join(map(str, ONLY))
    log = tmp_path / "stderr.log"
    proc = cli(
        "knee_phase1.yaml",
        "--dry-run",
        "--yes",
        "--only",
        only,
        "--seed",
        str(SEED),
        "--session",
        str(session),
        log=log,
    )
    kills = 0
    # kill points spread over the run (the units journaled when the kill comes), then a short random delay:
    # somewhere inside the next step (mid-trial, mid-write, ...; a dry run's steps take tens of ms, so a
    # longer delay would let a fast run finish before the later kills)
    total = len(Journal(reference_archive.parent / "journal.jsonl").units)
    targets = sorted(rng.sample(range(1, total - 1), 3))
    for round_, planned in enumerate(targets):
        target = max(planned, journal_units(session) + 1)
        if target >= total or not wait_for_units(proc, session, target):
            break
        time.sleep(rng.uniform(0.0, 0.05))
        if proc.poll() is not None:
            break
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        if proc.returncode == 0:  # it had finished and was already exiting when the kill came (exit 0 stands)
            break
        kills += 1
        assert proc.returncode == -signal.SIGKILL
        if round_ < len(targets) - 1:
            proc = cli("--resume", str(session), log=log)
    proc.wait(timeout=300)  # a resume still running (the run outpaced the kill points) runs to its end
    if (proc.returncode or 0) < 0:  # the last run was killed: resume it (two at once would not both run)
        proc = cli("--resume", str(session), log=log)
        proc.wait(timeout=300)
    assert proc.returncode == 0, proc.stderr()
    assert kills >= 2
    assert_same_data(reference_archive, session / "archive.h5")
    events = [
        json.loads(e)["kind"] for e in h5py.File(session / "archive.h5", "r")["session/events"].asstr()[:]
    ]
    # the resumes noticed the unclean stops (a run killed while still starting up leaves no trace, and one
    # killed while writing the final report had already recorded "finished", so counts can be below kills)
    assert events.count("resumed") >= 1 and events.count("interrupted") >= 1
    assert events[-1] == "finished"


def test_sigint_exits_130_resumable_and_nothing_lost(tmp_path: Path, reference_archive: Path) -> None:
    session = tmp_path / "sigint"
    only = ",".join(map(str, ONLY))
    proc = cli(
        "knee_phase1.yaml",
        "--dry-run",
        "--yes",
        "--only",
        only,
        "--seed",
        str(SEED),
        "--session",
        str(session),
        log=tmp_path / "err.log",
    )
    assert wait_for_units(proc, session, 2)  # the calibration and a trial: the stop lands among the trials
    proc.send_signal(signal.SIGINT)
    proc.wait(timeout=120)
    err = proc.stderr()
    assert proc.returncode == 130, err
    assert "--resume" in err and "Traceback" not in err
    done_before = journal_units(session)
    with h5py.File(session / "archive.h5", "r") as f:  # the stop consolidated what was finished
        assert f.attrs["status"] == "incomplete"
    assert resume(session, yes=True, force=False, realtime=False, quiet=True) == 0
    assert journal_units(session) > done_before
    assert_same_data(reference_archive, session / "archive.h5")


def test_truncated_unit_is_detected_and_redone(tmp_path: Path, reference_archive: Path) -> None:
    session = tmp_path / "truncated"
    assert run_dry(session) == 0
    victim = session / "units" / "trial__k12__on__2.h5"
    size = victim.stat().st_size
    with victim.open("r+b") as f:
        f.truncate(size // 2)
    (session / "archive.h5").unlink()
    assert resume(session, yes=True, force=False, realtime=False, quiet=True) == 0
    assert victim.stat().st_size == size
    journal = (session / "journal.jsonl").read_text()
    assert '"record": "invalidate"' in journal and "trial:k12:on:2" in journal
    assert_same_data(reference_archive, session / "archive.h5")


def test_resume_refuses_a_changed_protocol_unless_forced(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from protocol_runner.cli import main

    session = tmp_path / "changed"
    proc = cli(
        "knee_phase1.yaml",
        "--dry-run",
        "--yes",
        "--only",
        "12",
        "--session",
        str(session),
        log=tmp_path / "err.log",
    )
    assert wait_for_units(proc, session, 2)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    stored = next((session / "protocol").glob("*.yaml"))
    stored.write_text(stored.read_text().replace("periods: 8", "periods: 6"))
    assert main(["--resume", str(session), "--yes"]) == 2
    err = capsys.readouterr().err
    assert "protocol changed since the session began" in err and "--force" in err
    assert main(["--resume", str(session), "--yes", "--force"]) == 0
    with h5py.File(session / "archive.h5", "r") as f:
        kinds = [json.loads(e)["kind"] for e in f["session/events"].asstr()[:]]
        assert "operator_override" in kinds


def test_disk_full_stops_cleanly_and_resume_finishes(
    tmp_path: Path, reference_archive: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    session = tmp_path / "full"
    real = units_module._fsync_file
    calls = {"n": 0}

    def failing_fsync(path: Path) -> None:
        calls["n"] += 1
        if calls["n"] == 5:
            raise OSError(errno.ENOSPC, "No space left on device")
        real(path)

    monkeypatch.setattr(units_module, "_fsync_file", failing_fsync)
    with pytest.raises(DiskFull) as info:
        run_dry(session)
    assert "--resume" in info.value.message and info.value.exit_code == 130
    assert journal_units(session) == 4  # the four steps finished before the failing write are kept
    assert not list((session / "units").glob("*.partial"))
    monkeypatch.setattr(units_module, "_fsync_file", real)
    assert resume(session, yes=True, force=False, realtime=False, quiet=True) == 0
    assert_same_data(reference_archive, session / "archive.h5")


def test_failing_calibration_check_stops_with_exit_4(tmp_path: Path) -> None:
    from protocol_runner.cli import main

    protocols = Path(__file__).resolve().parents[2] / "protocols"
    text = (protocols / "knee_phase1.yaml").read_text()
    # the simulated joint answers with tau ~ 0.2 s (thesis §2.4.2): demand 0.3-0.35 s and the check fails
    bad = text.replace("time_constant_s: [0.1, 0.35]", "time_constant_s: [0.3, 0.35]")
    assert bad != text
    work = tmp_path / "protocols"
    import shutil

    shutil.copytree(protocols, work)
    (work / "strict.yaml").write_text(bad)
    session = tmp_path / "strict"
    code = main([str(work / "strict.yaml"), "--dry-run", "--yes", "--only", "12", "--session", str(session)])
    assert code == 4
    with h5py.File(session / "archive.h5", "r") as f:
        assert f.attrs["status"] == "aborted"
        check = f["calibration/rom_medium_spring/before"]
        assert check.attrs["verdict"] == "fail" and "time constant" in check.attrs["message"]
        assert "configurations/config_12/trials" not in f  # no trial ran after the failed check
    assert "cal:rom_medium_spring:before" not in Journal(session / "journal.jsonl").units  # redone on resume
    with pytest.raises(StoppedByCheck):
        resume(session, yes=True, force=False, realtime=False, quiet=True)
