"""The command's quick exit (process_exit): taken only when nothing is left to finish, else the normal exit.

Each case runs in its own interpreter with an object whose `__del__` writes a line when the interpreter tears
down its modules: that line is absent when `os._exit` skipped the teardown and present after a normal exit.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest

import protocol_runner
from protocol_runner.cli import main

TEARDOWN = "interpreter teardown of pid"
MARKER = f"""\
import os


class _Teardown:
    def __del__(self, write=os.write, pid=os.getpid()):
        write(2, f"{TEARDOWN} {{pid}}\\n".encode())


_teardown = _Teardown()
"""


BEFORE = "import sys\nfrom protocol_runner.process_exit import exit_now_if_safe\ntarget = sys.argv[1]\n"
AFTER = """
print("the last line, still in stdout's buffer")
exit_now_if_safe(3)
print("normal exit")
sys.exit(3)
"""


def _script(case: str) -> str:
    return MARKER + BEFORE + case + AFTER


def _run(case: str, target: Path) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}  # stdout to a pipe: block-buffered
    return subprocess.run(
        [sys.executable, "-c", _script(case), str(target)],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )


def _hdf5_complete(target: Path) -> None:
    with h5py.File(target, "r") as f:
        assert np.array_equal(f["x"][()], np.arange(1000.0))


def _text_complete(target: Path) -> None:
    assert target.read_text() == "kept\n" * 1000


def _nothing(target: Path) -> None:
    assert not target.exists()


CASES: dict[str, tuple[str, bool, Callable[[Path], None]]] = {
    # name: (what the script leaves behind, quick exit expected, what must be true of the target afterwards)
    "nothing left": ("pass", True, _nothing),
    "a daemon thread blocked": (
        "import threading; threading.Thread(target=threading.Event().wait, daemon=True).start()",
        True,
        _nothing,
    ),
    "an HDF5 file open for writing": (
        "import h5py, numpy; f = h5py.File(target, 'w'); f.create_dataset('x', data=numpy.arange(1000.0))",
        False,
        _hdf5_complete,
    ),
    "an HDF5 file open for reading": (
        "import h5py, numpy\n"
        "with h5py.File(target, 'w') as f: f.create_dataset('x', data=numpy.arange(1000.0))\n"
        "f = h5py.File(target, 'r')",
        False,
        _hdf5_complete,
    ),
    "a text file with buffered lines": (
        "out = open(target, 'w'); out.write('kept\\n' * 1000)",
        False,
        _text_complete,
    ),
    "a thread still writing": (
        "import threading\n"  # writes once the normal exit has begun (never before the check, however slow)
        "def work(): threading.main_thread().join(); open(target, 'w').write('kept\\n' * 1000)\n"
        "threading.Thread(target=work).start()",
        False,
        _text_complete,
    ),
    "a child process still writing": (
        "import atexit, multiprocessing\n"  # writes once the normal exit has begun (its atexit handlers)
        "def work(go):\n"
        "    if go.wait(120): open(target, 'w').write('kept\\n' * 1000)  # not left waiting for ever\n"
        "ctx = multiprocessing.get_context('fork'); go = ctx.Event()\n"
        "ctx.Process(target=work, args=(go,)).start(); atexit.register(go.set)",
        False,
        _text_complete,
    ),
}


@pytest.mark.parametrize("name", list(CASES))
def test_quick_exit_only_when_nothing_is_left_to_finish(name: str, tmp_path: Path) -> None:
    case, quick, complete = CASES[name]
    target = tmp_path / "left"
    done = _run(case, target)
    assert done.returncode == 3, done.stderr  # the code given, on both paths
    assert "the last line, still in stdout's buffer" in done.stdout  # flushed before os._exit
    torn_down = TEARDOWN in done.stderr
    assert torn_down is not quick, done.stderr
    assert ("normal exit" in done.stdout) is not quick
    complete(target)  # the normal exit finished what was left


def test_in_process_callers_get_the_exit_code_back(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--validate", "no_such_protocol.yaml"]) == 2  # returns: only cli.entry ends the process
    assert "no_such_protocol.yaml" in capsys.readouterr().err


def test_a_dry_run_ends_quickly_with_its_archive_report_and_output_complete(tmp_path: Path) -> None:
    """`python -m protocol_runner.cli` (what the `run-protocol` script runs): a short dry run skips the
    interpreter's teardown, and everything it wrote is complete."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "sitecustomize.py").write_text(MARKER)  # every process of the run gets the marker
    package_root = Path(protocol_runner.__file__).resolve().parents[1]  # this checkout's code, from anywhere
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    env["PYTHONPATH"] = os.pathsep.join((str(site), str(package_root)))
    session = tmp_path / "session"
    args = f"knee_phase1.yaml --dry-run --yes --seed 7 --only 12 --session {session}".split()
    log = tmp_path / "stderr.log"  # regular files open for writing (`run-protocol ... > out 2> log`)
    out = tmp_path / "stdout.log"
    with log.open("w") as stderr, out.open("w") as stdout:
        proc = subprocess.Popen(
            [sys.executable, "-m", "protocol_runner.cli", *args],
            stdout=stdout,
            stderr=stderr,
            text=True,
            env=env,
            cwd=tmp_path,
        )
    assert proc.wait(timeout=600) == 0, log.read_text()
    err = log.read_text()
    assert f"{TEARDOWN} {proc.pid}\n" not in err  # the quick exit was taken
    printed = [line for line in err.splitlines() if not line.startswith(TEARDOWN)]  # the fork server's
    assert printed[-1] == f"report:  {session / 'report.html'}", printed[-3:]  # the progress, all of it
    # the outcome, on standard output, flushed before the quick exit
    assert out.read_text().splitlines() == [f"done: {session / 'archive.h5'} and {session / 'report.html'}"]
    with h5py.File(session / "archive.h5", "r") as f:
        assert f.attrs["status"] == "complete"
        sizes: list[int] = []
        f.visititems(lambda _, obj: sizes.append(obj[()].size) if isinstance(obj, h5py.Dataset) else None)
    assert len(sizes) > 10 and sum(sizes) > 100_000  # every dataset read back
    assert (session / "report.html").read_text(encoding="utf-8").rstrip().endswith("</html>")


def test_the_run_protocol_script_is_the_entry_that_ends_the_process() -> None:
    import tomllib

    pyproject = Path(__file__).resolve().parents[1] / "pyproject.toml"
    scripts = tomllib.loads(pyproject.read_text(encoding="utf-8"))["project"]["scripts"]
    assert scripts["run-protocol"] == "protocol_runner.cli:entry"  # as `python -m protocol_runner.cli` runs
