"""The program needs nothing that only some platforms have: a dry run, `--report`, `--export` and
`--verify` work in an interpreter without `fcntl`, `os.pread`/`os.pwrite`, `signal.pthread_sigmask` and
`os.fork` (as on Windows), its analysis workers spawned. Before, the session lock imported `fcntl` and the
dry run failed at import."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import h5py

WITHOUT = """
import os, signal, sys
sys.modules["fcntl"] = None  # `import fcntl` raises ImportError
for name in ("pread", "pwrite", "fork", "forkpty"):
    if hasattr(os, name):
        delattr(os, name)
if hasattr(signal, "pthread_sigmask"):
    delattr(signal, "pthread_sigmask")
import multiprocessing
multiprocessing.set_start_method("spawn", force=True)
"""

CHECKED = """
import importlib, os, signal, multiprocessing
try:
    importlib.import_module("fcntl")
    raise SystemExit("fcntl is importable")
except ImportError:
    pass
assert not any(hasattr(os, n) for n in ("pread", "pwrite", "fork")) and not hasattr(signal, "pthread_sigmask")
assert multiprocessing.get_start_method() == "spawn"
from protocol_runner.cli import entry
entry()
"""


def run(site: Path, *args: str) -> subprocess.CompletedProcess[str]:
    """`run-protocol ARGS` in an interpreter (and worker processes) without the POSIX extras."""
    path = os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")])
    env = dict(os.environ, PYTHONPATH=path, PYTHONUNBUFFERED="1")
    return subprocess.run(
        [sys.executable, "-c", CHECKED, *args], capture_output=True, text=True, env=env, timeout=900
    )


def test_dry_run_report_export_and_verify_without_posix_extras(tmp_path: Path) -> None:
    site = tmp_path / "site"
    site.mkdir()
    (site / "sitecustomize.py").write_text(WITHOUT)  # every interpreter started here, the workers included
    session = tmp_path / "s"
    dry = run(
        site,
        "elbow_example.yaml",
        "--dry-run",
        "--seed",
        "7",
        "--only",
        "1",
        "--session",
        str(session),
    )
    assert dry.returncode == 0, dry.stderr
    with h5py.File(session / "archive.h5", "r") as f:
        assert f.attrs["status"] == "complete"
    report = run(site, "--report", str(session), "--output", str(tmp_path / "again.html"))
    assert report.returncode == 0, report.stderr
    assert (tmp_path / "again.html").stat().st_size > 0
    export = run(site, "--export", str(session), "--output", str(tmp_path / "tables"))
    assert export.returncode == 0, export.stderr
    assert (tmp_path / "tables" / "cycles.csv").is_file()
    verify = run(site, "--verify", str(session))
    assert verify.returncode == 0, verify.stderr + verify.stdout
