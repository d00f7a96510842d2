"""Ctrl-C on a terminal signals the whole process group: an
analysis worker still starting up must not die of it with a KeyboardInterrupt traceback; the session's main
process alone decides how to stop."""

from __future__ import annotations

import multiprocessing
import os
import signal
import subprocess
import sys
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import pytest

from protocol_runner.session.signals import StopFlag, sigint_blocked
from protocol_runner.session.workers import worker_init


def _answer() -> int:
    return 42


def test_worker_started_under_sigint_blocked_survives_a_sigint_while_starting() -> None:
    pool = ProcessPoolExecutor(
        max_workers=1, mp_context=multiprocessing.get_context("spawn"), initializer=worker_init
    )
    try:
        with sigint_blocked():
            future = pool.submit(_answer)  # the worker process is started here
        for pid in list(pool._processes):  # at once: the worker is still importing
            os.kill(pid, signal.SIGINT)
        assert future.result(timeout=120) == 42  # before: BrokenProcessPool (the worker died)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def test_sigint_arriving_while_blocked_is_delivered_afterwards_not_lost() -> None:
    got: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: got.append(signum))
    try:
        with sigint_blocked():
            signal.pthread_kill(threading.get_ident(), signal.SIGINT)  # to this thread, which blocks it
            assert got == []
        assert got == [signal.SIGINT]
    finally:
        signal.signal(signal.SIGINT, previous)


def test_two_ctrl_c_on_the_terminal_stop_without_a_traceback(tmp_path: Path) -> None:
    """Ctrl-C twice, as a terminal sends it (to the whole process group), just as the analysis workers start."""
    session = tmp_path / "ctrl-c"
    log = tmp_path / "stderr.log"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    # two sets: when the first set's last calibration check is journaled, its analyses go to the workers
    # while the second set's trials run (with one set only, the session could be writing its report by the
    # time the Ctrl-C lands)
    args = ["knee_phase1.yaml", "--dry-run", "--yes", "--only", "12,21", "--session", str(session)]
    with log.open("wb") as err:
        proc = subprocess.Popen(
            [sys.executable, "-m", "protocol_runner.cli", *args],
            stdout=subprocess.DEVNULL,
            stderr=err,
            env=env,
            start_new_session=True,  # its own process group, like a shell job
        )
        try:
            deadline = time.monotonic() + 120
            journal = session / "journal.jsonl"
            while not (journal.exists() and "cal:rom_medium_spring:after" in journal.read_text()):
                assert proc.poll() is None and time.monotonic() < deadline, log.read_text()
                time.sleep(0.005)
            os.killpg(proc.pid, signal.SIGINT)  # the workers for processing are starting now
            time.sleep(0.05)
            os.killpg(proc.pid, signal.SIGINT)
            code = proc.wait(timeout=120)
        finally:
            if proc.poll() is None:
                proc.kill()
    text = log.read_text()
    assert "Traceback" not in text, text
    assert code == 130, text


class _RaisesOnCollection:
    def __del__(self) -> None:
        raise KeyboardInterrupt  # what a second Ctrl-C does when it lands inside a finaliser


def test_a_second_ctrl_c_dropped_inside_a_finaliser_is_delivered_again() -> None:
    """Python cannot raise out of a finaliser or weakref callback: it prints "Exception ignored" with a
    traceback and drops the exception. During a stop, the flag delivers that interrupt again."""
    flag = StopFlag()
    flag.install()
    try:
        flag.request("SIGINT")  # the first Ctrl-C: a stop is under way
        with pytest.raises(KeyboardInterrupt):
            obj = _RaisesOnCollection()
            del obj
            deadline = time.monotonic() + 5.0
            while time.monotonic() < deadline:
                time.sleep(0.001)
    finally:
        flag.uninstall()


SESSION = """
import sys, time
from concurrent.futures import ProcessPoolExecutor
from protocol_runner.session.workers import worker_context, worker_init
if __name__ == "__main__":
    pool = ProcessPoolExecutor(max_workers=1, mp_context=worker_context(), initializer=worker_init)
    print(pool.submit(__import__("os").getpid).result(), flush=True)
    pool.submit(time.sleep, 600)
    time.sleep(600)
"""


def test_a_worker_dies_at_once_with_its_session_killed_with_sigkill(tmp_path: Path) -> None:
    """A killed session must leave no worker behind writing units (a resume may start at once)."""
    script = tmp_path / "session.py"
    script.write_text(SESSION, encoding="utf-8")
    with subprocess.Popen(
        [sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True
    ) as proc:
        assert proc.stdout is not None
        worker = int(proc.stdout.readline())
        time.sleep(0.5)  # the worker sleeps in its task
        assert Path(f"/proc/{worker}").exists()
        proc.kill()
        proc.wait(timeout=60)
        deadline = time.monotonic() + 10  # at once in practice; without the watch it would sleep 600 s
        while Path(f"/proc/{worker}").exists() and "zombie" not in _state(worker):
            assert time.monotonic() < deadline, "the worker outlived its killed session"
            time.sleep(0.01)


def _state(pid: int) -> str:
    try:
        return next(
            line for line in Path(f"/proc/{pid}/status").read_text().splitlines() if line.startswith("State:")
        )
    except (OSError, StopIteration):
        return "zombie (gone)"
