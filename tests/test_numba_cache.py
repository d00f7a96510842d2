"""Where the compiled kernels are cached: the user's cache directory; where no directory is writable (a
read-only install run by a user without a writable home), the kernels are compiled in every run after one
warning line, never a traceback."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from protocol_runner import numba_cache

SRC = Path(__file__).resolve().parents[1] / "src"


def test_the_user_cache_directory_follows_the_platform(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    monkeypatch.setenv("LOCALAPPDATA", str(tmp_path / "local"))
    monkeypatch.setattr(sys, "platform", "linux")
    assert numba_cache.user_cache_dir() == tmp_path / "xdg" / "protocol-runner" / "numba"
    monkeypatch.setenv("XDG_CACHE_HOME", "relative/cache")  # not absolute: ignored, as XDG says
    assert numba_cache.user_cache_dir() == tmp_path / ".cache" / "protocol-runner" / "numba"
    monkeypatch.setattr(sys, "platform", "darwin")
    assert numba_cache.user_cache_dir() == tmp_path / "Library" / "Caches" / "protocol-runner" / "numba"
    monkeypatch.setattr(sys, "platform", "win32")
    assert numba_cache.user_cache_dir() == tmp_path / "local" / "protocol-runner" / "numba"


def test_importing_the_package_points_numba_at_the_user_cache(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", numba_cache.SWITCH)}
    env |= {"XDG_CACHE_HOME": str(tmp_path), "PYTHONPATH": str(SRC)}
    code = "import protocol_runner, numba; print(numba.config.CACHE_DIR)"
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert done.stdout.strip() == str(tmp_path / "protocol-runner" / "numba")


@pytest.mark.slow
def test_without_a_writable_cache_a_dry_run_compiles_and_warns_once(tmp_path: Path) -> None:
    blocker = tmp_path / "not-a-directory"
    blocker.write_text("")  # a directory cannot be made under a file, whoever runs the test (root too)
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", numba_cache.SWITCH)}
    env |= {"HOME": str(blocker), "XDG_CACHE_HOME": str(blocker / "cache"), "PYTHONPATH": str(SRC)}
    args = ["elbow_example.yaml", "--dry-run", "--only", "1", "--session", str(tmp_path / "s")]
    done = subprocess.run(
        [sys.executable, "-m", "protocol_runner", *args],
        env=env,
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    warnings = [line for line in done.stderr.splitlines() if "no writable cache directory" in line]
    assert len(warnings) == 1, done.stderr
    assert (tmp_path / "s" / "archive.h5").is_file() and (tmp_path / "s" / "report.html").is_file()
