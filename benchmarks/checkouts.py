"""What the benchmarks do to a checkout they run from its `src/` before timing it."""

from __future__ import annotations

import subprocess
import sys
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
