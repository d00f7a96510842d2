"""A session's lock, journal, log and units folder are never followed through a symbolic link: a link
planted there is refused (exit 2, naming it) and its target is left as it was. Before, a linked `.lock`
had its target truncated and overwritten with a PID, a linked `units/` had every `*.partial` file of its
target deleted, and a linked journal or log had lines appended to its target."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from protocol_runner.cli import main

from .conftest import copy_session

pytestmark = pytest.mark.skipif(not hasattr(os, "symlink"), reason="needs symbolic links")


def unfinished_copy(reference_archive: Path, to: Path) -> Path:
    """A copy of the reference session without its archive and report: a resume has work to do."""
    session = copy_session(reference_archive, to)
    (session / "archive.h5").unlink()
    (session / "report.html").unlink()
    return session


@pytest.mark.parametrize("name", [".lock", "session.log", "journal.jsonl"])
def test_a_linked_session_file_is_refused_and_its_target_untouched(
    name: str, tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = unfinished_copy(reference_archive, tmp_path / "s")
    victim = tmp_path / "elsewhere" / "precious.txt"
    victim.parent.mkdir()
    if (session / name).exists():
        shutil.move(session / name, victim)  # the link points at the session's own content, moved away
    else:
        victim.write_bytes(b"precious\n")
    before = victim.read_bytes()
    (session / name).symlink_to(victim)
    assert main(["--resume", str(session), "--yes"]) == 2
    err = capsys.readouterr().err
    assert str(session / name) in err and "symbolic link" in err and "Traceback" not in err
    assert victim.read_bytes() == before
    assert not (session / "archive.h5").exists()


def test_a_linked_units_folder_is_refused_and_its_target_untouched(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = unfinished_copy(reference_archive, tmp_path / "s")
    target = tmp_path / "elsewhere"
    shutil.move(session / "units", target)
    (target / "someone_elses.partial").write_bytes(b"not a unit of this session")
    before = sorted(p.name for p in target.iterdir())
    (session / "units").symlink_to(target, target_is_directory=True)
    assert main(["--resume", str(session), "--yes"]) == 2
    err = capsys.readouterr().err
    assert str(session / "units") in err and "symbolic link" in err
    assert sorted(p.name for p in target.iterdir()) == before


def test_a_session_directory_that_is_a_link_is_used(tmp_path: Path, reference_archive: Path) -> None:
    real = unfinished_copy(reference_archive, tmp_path / "real")
    linked = tmp_path / "linked"
    linked.symlink_to(real, target_is_directory=True)
    assert main(["--resume", str(linked), "--yes"]) == 0
    assert (real / "archive.h5").is_file() and (real / "report.html").is_file()
