"""Where numba keeps the compiled kernels between runs: the user's cache directory.

The package's `__init__` points `NUMBA_CACHE_DIR` (unless set) at `<user cache directory>/protocol-runner/
numba` before any module imports numba, and the modules with compiled kernels ask `cache_enabled()`
whether to cache at all: when that directory is not writable (numba's `cache=True` would raise at import)
they compile in every run instead, after one warning line. `PROTOCOL_RUNNER_NUMBA_CACHE=0` turns it off.
"""

from __future__ import annotations

import contextlib
import functools
import os
import sys
import tempfile
from pathlib import Path

SWITCH = "PROTOCOL_RUNNER_NUMBA_CACHE"
"""Environment variable: "0" compiles the kernels in every run, caching nothing (set by `cache_enabled`
when no directory is writable, so that the processes this one starts do not warn again)."""


def user_cache_dir() -> Path:
    """The platform's per-user cache directory for this package's compiled kernels."""
    home = Path.home()
    if sys.platform == "win32":
        base = Path(os.environ.get("LOCALAPPDATA") or home / "AppData" / "Local")
    elif sys.platform == "darwin":
        base = home / "Library" / "Caches"
    else:
        xdg = os.environ.get("XDG_CACHE_HOME", "")
        base = Path(xdg) if os.path.isabs(xdg) else home / ".cache"  # a relative value is ignored (XDG)
    return base / "protocol-runner" / "numba"


def point_numba_at_the_user_cache() -> None:
    """Set `NUMBA_CACHE_DIR` to `user_cache_dir()` unless it is set. Creates nothing; cheap."""
    if "NUMBA_CACHE_DIR" not in os.environ:
        with contextlib.suppress(RuntimeError):  # no home directory to be found: numba's own rules apply
            os.environ["NUMBA_CACHE_DIR"] = str(user_cache_dir())


def will_compile() -> bool:
    """Whether the kernels are compiled in this run rather than read from the cache: the cache is off, or
    its directory holds nothing yet (the first run after installing, or after the cache was cleared)."""
    if not cache_enabled():
        return True
    directory = Path(os.environ["NUMBA_CACHE_DIR"])
    return not any(directory.iterdir())


@functools.cache
def cache_enabled() -> bool:
    """Whether `@njit(cache=...)` should cache: `NUMBA_CACHE_DIR` names a directory that exists or can be
    made and takes a file. Otherwise one warning line on standard error, and False."""
    if os.environ.get(SWITCH) == "0":
        return False
    point_numba_at_the_user_cache()
    given = os.environ.get("NUMBA_CACHE_DIR")
    if not given:
        reason = "no home directory"
    else:
        try:
            Path(given).mkdir(parents=True, exist_ok=True)
            tempfile.TemporaryFile(dir=given).close()
            return True
        except OSError as exc:
            reason = f"{given}: {exc.strerror or exc}"
    print(
        f"protocol-runner: warning: no writable cache directory for the compiled kernels ({reason}); they are "
        "compiled again in every run (15-60 s). Set NUMBA_CACHE_DIR to a writable directory to keep them.",
        file=sys.stderr,
        flush=True,
    )
    os.environ[SWITCH] = "0"
    return False
