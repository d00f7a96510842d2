"""A running campaign survives its output going away and stops cleanly when its terminal closes:

- SIGHUP (terminal or SSH connection closed) stops at the next safe point like SIGTERM: the stop is
  journaled, the archive consolidated (incomplete, resumable) and the exit status is 130; before, the
  process died at once (exit 129) with nothing journaled and the joint not parked;
- standard output and error whose reader went away (`2>&1 | head -2`, `| true`) or that were closed before
  the start (`2>&-`) never stop the campaign: it completes (exit 0), its lines are in session.log, and no
  traceback is written anywhere; before, `| head -2` stopped it after the first step;
- a second Ctrl-C ends the process within a bounded time even when what it waits for never returns.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import pytest

posix_only = pytest.mark.skipif(os.name == "nt", reason="POSIX signals and shell redirections")
SHORT = ["elbow_example.yaml", "--dry-run", "--seed", "7", "--only", "1"]
CLI = [sys.executable, "-m", "protocol_runner.cli"]


def _env() -> dict[str, str]:
    return dict(os.environ, PYTHONUNBUFFERED="1")


def _events(session: Path) -> list[dict[str, str]]:
    lines = (session / "journal.jsonl").read_text().splitlines()
    return [r for r in map(json.loads, lines) if r.get("record") == "event"]


def _wait_for_first_unit(session: Path, proc: subprocess.Popen[bytes], what: Path) -> None:
    journal = session / "journal.jsonl"
    deadline = time.monotonic() + 300
    while not (journal.exists() and '"record": "unit"' in journal.read_text()):
        assert proc.poll() is None and time.monotonic() < deadline, what.read_text()
        time.sleep(0.01)


def _hangup_stops() -> None:
    """In the child: SIGHUP as a terminal delivers it. A test run under `nohup` inherits SIGHUP ignored,
    and the program keeps an ignored SIGHUP ignored (`nohup run-protocol ...` is meant to survive a closed
    terminal), so without this the hang-up would not reach it."""
    signal.signal(signal.SIGHUP, signal.SIG_DFL)


def _archive_status(session: Path) -> str:
    with h5py.File(session / "archive.h5", "r") as f:
        return str(f.attrs["status"])


@posix_only
def test_sighup_stops_at_the_next_safe_point_journaled_and_resumable(tmp_path: Path) -> None:
    session, err = tmp_path / "s", tmp_path / "stderr.txt"
    with err.open("wb") as f:  # --realtime: the campaign is still moving when the terminal closes
        proc = subprocess.Popen(
            [*CLI, *SHORT, "--realtime", "--session", str(session)],
            stderr=f,
            env=_env(),
            preexec_fn=_hangup_stops,
        )
    try:
        _wait_for_first_unit(session, proc, err)
        proc.send_signal(signal.SIGHUP)
        code = proc.wait(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    text = err.read_text()
    assert code == 130, text
    assert "Traceback" not in text
    stops = [e for e in _events(session) if e["kind"] == "interrupted"]
    assert stops and "SIGHUP" in stops[-1]["detail"], _events(session)
    assert _archive_status(session) == "incomplete"
    assert "run-protocol --resume" in text


def _complete_without_traceback(session: Path, code: int) -> None:
    log = (session / "session.log").read_text()
    assert code == 0, log
    assert "Traceback" not in log and "internal error" not in log
    assert _archive_status(session) == "complete"
    assert "[13/13] report" in log  # every progress line is in the log, shown or not


@posix_only
def test_a_pipe_whose_reader_ends_after_two_lines_does_not_stop_the_campaign(tmp_path: Path) -> None:
    session = tmp_path / "s"
    proc = subprocess.Popen(
        [*CLI, *SHORT, "--session", str(session)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        env=_env(),
    )
    assert proc.stdout is not None
    shown = [proc.stdout.readline() for _ in range(2)]  # `| head -2`
    proc.stdout.close()
    code = proc.wait(timeout=600)
    assert all(shown)
    _complete_without_traceback(session, code)


@posix_only
@pytest.mark.parametrize("redirect", ["2>&1 | true", "2>&-", ">&- 2>&-"])
def test_output_gone_from_the_start_does_not_stop_the_campaign(redirect: str, tmp_path: Path) -> None:
    session, out = tmp_path / "s", tmp_path / "shell.txt"
    command = " ".join(map(_quote, [*CLI, *SHORT, "--session", str(session)]))
    with out.open("wb") as f:
        done = subprocess.run(
            ["sh", "-c", f"{command} {redirect}; echo exit=$?"], stdout=f, stderr=f, env=_env(), timeout=600
        )
    said = out.read_text()
    assert done.returncode == 0 and "Traceback" not in said and "Exception ignored" not in said, said
    if "|" not in redirect:
        assert "exit=0" in said, said
    _complete_without_traceback(session, 0)


def _quote(word: str) -> str:
    return "'" + word.replace("'", "'\\''") + "'"


HANGS_WHEN_KILLING = """
import sys, threading
from protocol_runner.session import workers
workers.AnalysisPool.kill = lambda self: threading.Event().wait()  # what it waits for never comes
from protocol_runner.cli import entry
sys.argv[1:] = sys.argv[2:]
entry()
"""


@posix_only
def test_a_second_ctrl_c_ends_the_process_even_when_stopping_the_workers_hangs(tmp_path: Path) -> None:
    session, err = tmp_path / "s", tmp_path / "stderr.txt"
    with err.open("wb") as f:
        proc = subprocess.Popen(
            [sys.executable, "-c", HANGS_WHEN_KILLING, "--", *SHORT, "--realtime", "--session", str(session)],
            stderr=f,
            env=_env(),
            start_new_session=True,
        )
    try:
        _wait_for_first_unit(session, proc, err)
        os.killpg(proc.pid, signal.SIGINT)
        time.sleep(0.05)
        os.killpg(proc.pid, signal.SIGINT)
        code = proc.wait(timeout=120)  # the deadline is 10 s: far inside
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert code == 130, err.read_text()


@posix_only
def test_a_hangup_ignored_by_nohup_stays_ignored() -> None:
    """`nohup run-protocol ...` ignores SIGHUP so that closing the terminal does not stop the campaign."""
    from protocol_runner.session.signals import StopFlag

    previous = signal.signal(signal.SIGHUP, signal.SIG_IGN)
    flag = StopFlag()
    try:
        flag.install()
        assert signal.getsignal(signal.SIGHUP) == signal.SIG_IGN
        assert signal.getsignal(signal.SIGINT) == flag._handler
    finally:
        flag.uninstall()
        signal.signal(signal.SIGHUP, previous)
