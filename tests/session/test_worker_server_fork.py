"""The analysis workers' fork server is a fork of the command-line session (issue 20: what both import is
imported once), on Linux; elsewhere, or when the session already runs a thread, the server is a fresh
interpreter as multiprocessing starts it (session/worker_start.py)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(
    sys.platform != "linux" or sys.version_info[:2] not in ((3, 11), (3, 12)),
    reason="the session forks its fork server on Linux with CPython 3.11/3.12 only",
)

# A session's script: it registers a module that exists only in its own memory (no file could import it),
# starts the server as a command-line session does, and asks a worker what it sees.
SESSION = """
import json, os, signal, sys, threading, time, types

def probe():
    marker = sys.modules.get("_only_in_the_session")
    with open(f"/proc/{os.getppid()}/stat") as stat:
        server_parent = int(stat.read().rsplit(")", 1)[1].split()[1])
    with open(f"/proc/{os.getppid()}/cmdline", "rb") as cmdline:
        server_command = cmdline.read().decode()
    with open(f"/proc/{os.getppid()}/status") as status:
        ignored = next(int(line.split()[1], 16) for line in status if line.startswith("SigIgn:"))
    return {
        "worker": os.getpid(),
        "server_ignores_sigint": bool(ignored & (1 << (signal.SIGINT - 1))),
        "marker": getattr(marker, "session_pid", None),
        "server": os.getppid(),
        "server_parent": server_parent,
        "server_command": server_command,
        "numpy_before_the_task": "numpy" in sys.modules,
    }

if __name__ == "__main__":
    marker = types.ModuleType("_only_in_the_session")
    marker.session_pid = os.getpid()
    sys.modules["_only_in_the_session"] = marker
    if sys.argv[1] == "thread":  # a session already running a thread must not fork
        stop = threading.Event()
        threading.Thread(target=stop.wait, daemon=True).start()
    from concurrent.futures import ProcessPoolExecutor
    from protocol_runner.session.worker_start import start_worker_server, worker_context, worker_init

    start_worker_server(fork_session=True)
    with ProcessPoolExecutor(1, mp_context=worker_context(), initializer=worker_init) as pool:
        seen = pool.submit(probe).result(timeout=120)
        if sys.argv[1] == "kill":  # the worker sleeps in a task while the test kills this session
            print(json.dumps(dict(seen, session=os.getpid())), flush=True)
            pool.submit(time.sleep, 600).result()
    if sys.argv[1] == "thread":
        stop.set()
    print(json.dumps(dict(seen, session=os.getpid())))
"""


def _session(tmp_path: Path, mode: str) -> dict[str, object]:
    script = tmp_path / "session.py"
    script.write_text(SESSION)
    done = subprocess.run(
        [sys.executable, str(script), mode], capture_output=True, text=True, timeout=240, check=False
    )
    assert done.returncode == 0, done.stderr
    seen: dict[str, object] = json.loads(done.stdout.strip().splitlines()[-1])
    return seen


def test_the_workers_are_forked_from_a_fork_of_the_session(tmp_path: Path) -> None:
    seen = _session(tmp_path, "fork")
    assert seen["server"] != seen["session"]  # a worker's parent is the server ...
    assert seen["server_parent"] == seen["session"]  # ... whose parent is the session
    # ... and which is the session's copy: a module registered in the session's memory only, before the
    # server started, is there in the worker; the server runs the session's command, not `python -c`
    assert seen["marker"] == seen["session"]
    assert "multiprocessing.forkserver" not in str(seen["server_command"])
    assert seen["numpy_before_the_task"] is True
    assert (
        seen["server_ignores_sigint"] is True
    )  # a terminal's Ctrl-C reaches it too: only the session decides


def test_the_forked_server_and_its_workers_end_with_a_session_killed_with_sigkill(tmp_path: Path) -> None:
    """As with a fresh server (test_worker_signals.py): the worker watches the session, and the server ends
    once no process holds the alive pipe (it closed its own copy when it was forked)."""
    script = tmp_path / "session.py"
    script.write_text(SESSION)
    with subprocess.Popen(
        [sys.executable, str(script), "kill"], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True
    ) as proc:
        assert proc.stdout is not None
        seen = json.loads(proc.stdout.readline())
        assert seen["marker"] == seen["session"]  # the forked server
        time.sleep(0.3)  # the worker sleeps in its task
        worker, server = int(seen["worker"]), int(seen["server"])
        assert _running(worker) and _running(server)
        proc.kill()
        proc.wait(timeout=60)
        deadline = time.monotonic() + 10
        try:
            while _running(worker) or _running(server):
                assert time.monotonic() < deadline, "the worker or the server outlived the killed session"
                time.sleep(0.01)
        finally:  # none left behind if they did
            for pid in (worker, server):
                if _running(pid):
                    os.kill(pid, signal.SIGKILL)


def _running(pid: int) -> bool:
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    return "zombie" not in next(line for line in status.splitlines() if line.startswith("State:"))


def test_a_session_running_a_thread_starts_a_fresh_server_instead(tmp_path: Path) -> None:
    seen = _session(tmp_path, "thread")
    assert seen["server_parent"] == seen["session"]
    assert seen["marker"] is None  # a fresh interpreter: nothing of the session's memory
    assert "multiprocessing.forkserver" in str(seen["server_command"])


def test_the_command_line_session_forks_its_server(tmp_path: Path) -> None:
    """`python -m protocol_runner.cli` (as the run-protocol command): the session's child that forks the
    workers runs the session's own command line, not a fresh `python -c ... forkserver` interpreter."""
    session = tmp_path / "s"
    args = ["knee_phase1.yaml", "--dry-run", "--yes", "--only", "12", "--session", str(session)]
    command = [sys.executable, "-m", "protocol_runner.cli", *args]
    proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    own = "\0".join(command) + "\0"  # as /proc shows it (read at once, it may still be empty: exec under way)
    commands: dict[int, str] = {}
    server: int | None = None
    try:
        deadline = time.monotonic() + 120
        # other children come and go (h5py's import runs `uname -p`; the resource tracker is spawned, and
        # shows the session's command line until its exec): watch until the server is seen and stays so
        while server is None and proc.poll() is None and time.monotonic() < deadline:
            commands.update(_children_commands(proc.pid))
            for pid, line in commands.items():
                if "multiprocessing.forkserver" in line:
                    server = pid
                elif line == own:
                    time.sleep(0.05)  # a child between fork and exec would have exec'd by now
                    if _command(pid) == own:
                        server = pid
            time.sleep(0.01)
    finally:
        _, err = proc.communicate(timeout=240)
    assert proc.returncode == 0, err.decode()
    assert server is not None, f"no fork server among the session's children: {commands}"
    assert "multiprocessing.forkserver" not in commands[server]  # not a fresh interpreter
    assert commands[server] == own  # the server: a fork of the session


def _command(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().decode()
    except OSError:
        return ""


def _children_commands(parent: int) -> dict[int, str]:
    found: dict[int, str] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        command = _command(int(entry))
        if not command:  # a child in the middle of its exec, or ending: not known yet
            continue
        if int(stat.rsplit(")", 1)[1].split()[1]) == parent and "resource_tracker" not in command:
            found[int(entry)] = command
    return found


NUMBA_TARGET = """
import json, sys
sys.path.insert(0, {src!r})
from protocol_runner.session import worker_start
if sys.argv[1] == "shared":
    assert worker_start._import_shared()
else:  # the same modules, without loading numba's target
    import importlib
    for name in worker_start.SHARED:
        importlib.import_module(name)
before = set(sys.modules)
from protocol_runner.models.bouc_wen.kernels import sgn
assert sgn(-2.0) == -1.0  # a compiled call (from numba's cache, or compiled)
print(json.dumps(sorted(m for m in set(sys.modules) - before if m.startswith("numba."))))
"""


def test_numba_s_target_is_loaded_with_what_the_session_and_its_fork_server_share() -> None:
    """`_import_shared` (run before the session forks its fork server) also loads numba's CPU target, which
    numba otherwise loads (importing its ~100 implementation modules, 0.09 s of CPU) at a process's first
    compiled call: in the session at its first simulated step and again in the server's warm-up."""
    from tests.session.python_child import child_stdout

    src = str(Path(__file__).resolve().parents[2] / "src")
    after_shared = json.loads(child_stdout(NUMBA_TARGET.format(src=src), "shared").strip().splitlines()[-1])
    imports_only = json.loads(child_stdout(NUMBA_TARGET.format(src=src), "imports").strip().splitlines()[-1])
    assert after_shared == []
    assert len(imports_only) > 20  # what the first compiled call loads when the target was not loaded
