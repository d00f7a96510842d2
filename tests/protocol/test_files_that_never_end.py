"""A FIFO, a device or a huge file given where a protocol, a rig file, a trajectory, a table or a unit
belongs is refused unread, at once (a review's `--validate` of a FIFO waited forever, `--verify` of a session
with a FIFO in units/ too, and a 289 MB trajectory CSV took 80 s and 9.6 GB of memory before failing)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.protocol.loader import find_protocol
from protocol_runner.tables import MAX_TABLE_BYTES, read_table_text

CLI = [sys.executable, "-m", "protocol_runner.cli"]


def _cli(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*CLI, *args], cwd=cwd, capture_output=True, text=True, timeout=60)


def test_a_fifo_as_the_protocol_is_refused_at_once(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "fifo.yaml")
    done = _cli("--validate", "fifo.yaml", cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert "fifo.yaml: not a regular file" in done.stderr and "Traceback" not in done.stderr


def test_a_fifo_as_a_trajectory_file_is_refused_at_once(tmp_path: Path) -> None:
    protocol = find_protocol("elbow_example.yaml")
    shutil.copy(protocol, tmp_path / "p.yaml")
    text = (tmp_path / "p.yaml").read_text()
    start = text.index("  sine: {kind: sinusoid")
    end = text.index("\n", start)
    (tmp_path / "p.yaml").write_text(text[:start] + "  sine: {kind: file, file: motion.csv}" + text[end:])
    os.mkfifo(tmp_path / "motion.csv")
    done = _cli("--validate", "p.yaml", cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert "motion.csv: not a regular file" in done.stderr and "Traceback" not in done.stderr


def test_a_table_over_the_limit_is_refused_before_it_is_read(tmp_path: Path) -> None:
    big = tmp_path / "big.csv"
    with big.open("wb") as f:
        f.truncate(MAX_TABLE_BYTES + 1)  # sparse: no time or disk spent writing it
    with pytest.raises(InvalidInput, match=r"big\.csv: \d+ bytes, more than the \d+ \(64 MiB\)"):
        read_table_text(big, "trajectory file")
    assert read_table_text(_small(tmp_path), "trajectory file").startswith("time_s")


def _small(tmp_path: Path) -> Path:
    path = tmp_path / "small.csv"
    path.write_text("time_s,angle_deg\n0,10\n1,20\n")
    return path


def test_verify_names_a_fifo_in_units_and_an_archive_that_is_a_directory(tmp_path: Path) -> None:
    session = tmp_path / "s"
    (session / "units").mkdir(parents=True)
    os.mkfifo(session / "units" / "trial__k01__on__1.h5")
    (session / "archive.h5").mkdir()
    done = _cli("--verify", str(session), cwd=tmp_path)
    assert done.returncode != 0 and "Traceback" not in done.stderr, done.stderr
    out = done.stdout + done.stderr
    assert "trial__k01__on__1.h5: not a regular file" in out, out
    assert "archive.h5: not a regular file" in out, out


def test_a_fifo_as_a_referenced_file_is_said_to_be_one_not_missing(tmp_path: Path) -> None:
    protocol = find_protocol("knee_phase1.yaml")
    shutil.copytree(protocol.parent, tmp_path / "p")
    path = tmp_path / "p" / "knee_phase1.yaml"
    text = path.read_text()
    assert "  reference_dataset: null" in text
    path.write_text(text.replace("  reference_dataset: null", "  reference_dataset: emu.csv", 1))
    os.mkfifo(tmp_path / "p" / "emu.csv")
    done = _cli("--validate", "knee_phase1.yaml", cwd=tmp_path / "p")
    assert done.returncode == 2, done.stderr
    assert "reference dataset emu.csv is not a regular file" in done.stderr and "not found" not in done.stderr
