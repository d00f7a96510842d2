"""The session lock (filelock): a second process is refused naming the holder's PID, a lock left by a
process killed with -9 does not block, and a lock file that is a symbolic link is refused, its target
untouched."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.session.lock import session_lock

HOLD = """
import sys, time
from pathlib import Path
from protocol_runner.session.lock import session_lock
with session_lock(Path(sys.argv[1])):
    print("held", flush=True)
    time.sleep(600)
"""


def test_a_second_process_is_refused_with_the_holders_pid_and_a_killed_holder_does_not_block(
    tmp_path: Path,
) -> None:
    holder = subprocess.Popen([sys.executable, "-c", HOLD, str(tmp_path)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        in_use = rf"in use by another run-protocol \(pid {holder.pid}\)"
        with pytest.raises(InvalidInput, match=in_use), session_lock(tmp_path):
            pass
    finally:
        holder.send_signal(signal.SIGKILL if hasattr(signal, "SIGKILL") else signal.SIGTERM)
        holder.wait(timeout=60)
        assert holder.stdout is not None
        holder.stdout.close()
    with session_lock(tmp_path):  # the lock died with its holder
        assert (tmp_path / ".lock.pid").read_text() == str(os.getpid())


@pytest.mark.skipif(not hasattr(os, "symlink"), reason="needs symbolic links")
def test_a_lock_file_that_is_a_link_is_refused(tmp_path: Path) -> None:
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me\n")
    session = tmp_path / "s"
    session.mkdir()
    (session / ".lock").symlink_to(victim)
    with pytest.raises(InvalidInput, match="symbolic link"), session_lock(session):
        pass
    assert victim.read_text() == "keep me\n"
