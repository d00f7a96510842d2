"""What the benchmarks do to a checkout they run from its `src/` before timing it."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import time
from pathlib import Path


def byte_compile(src: Path) -> None:
    """Byte-compile a checkout's sources run from `src/`, as `pip install` does for the installed package.
    With PYTHONDONTWRITEBYTECODE set (as on the shared machine) every run would otherwise compile the
    package's ~220 modules again, in the session and in the workers for what they import after their fork
    (measured: about 0.5 s of CPU and 0.6-0.9 s of wall time on the knee dry run), which a user's installed
    copy never does."""
    subprocess.run(
        [sys.executable, "-m", "compileall", "-q", str(src)], check=True, stdout=subprocess.DEVNULL
    )


def become_subreaper() -> None:
    """Linux: processes the run leaves behind (the analysis workers' fork server, which outlives the
    session by a moment and reaps its own workers) are re-parented to this benchmark instead of init, so
    that their CPU is counted when `orphans_cpu_s` reaps them."""
    with contextlib.suppress(Exception):
        import ctypes

        pr_set_child_subreaper = 36
        ctypes.CDLL(None, use_errno=True).prctl(pr_set_child_subreaper, 1)


def orphans_cpu_s(timeout_s: float = 30.0) -> float:
    """User + system CPU of the run's descendants that outlived it (reaped here, see `become_subreaper`)."""
    total = 0.0
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            pid, _, usage = os.wait4(-1, os.WNOHANG)
        except ChildProcessError:
            break
        if pid == 0:
            time.sleep(0.01)
            continue
        total += usage.ru_utime + usage.ru_stime
    return total
