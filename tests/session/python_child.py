"""A Python snippet run in a fresh interpreter (this one's), for facts about process start-up that an
already-warm test process cannot show: what it prints on stdout."""

from __future__ import annotations

import subprocess
import sys


def child_stdout(script: str, *args: str, timeout: float = 300.0) -> str:
    """Run `script` with `args` in a new interpreter; its stdout (it must exit 0)."""
    done = subprocess.run(
        [sys.executable, "-c", script, *args], capture_output=True, text=True, check=True, timeout=timeout
    )
    return done.stdout
