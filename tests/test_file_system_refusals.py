"""What the file system refuses is said in one line naming the path (errors.file_system_refusal): for a
rename, both paths, since the one in the way is often the second (a directory where a unit belongs)."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import pytest

from protocol_runner.errors import file_system_refusal


def test_a_rename_onto_a_directory_names_both_paths(tmp_path: Path) -> None:
    partial = tmp_path / "unit.h5.partial"
    partial.write_bytes(b"x")
    final = tmp_path / "unit.h5"
    final.mkdir()
    with pytest.raises(OSError) as caught:
        os.replace(partial, final)
    message = file_system_refusal(caught.value)
    assert message == f"cannot move {partial} to {final}: Is a directory"


def test_one_path_is_named_with_the_hint_for_what_to_do(tmp_path: Path) -> None:
    exc = PermissionError(errno.EACCES, "Permission denied", str(tmp_path / "report.html"))
    assert (
        file_system_refusal(exc)
        == f"cannot use {tmp_path / 'report.html'}: Permission denied; check the permissions"
    )
    read_only = OSError(errno.EROFS, "Read-only file system", str(tmp_path))
    assert file_system_refusal(read_only) == (
        f"cannot use {tmp_path}: Read-only file system; use a writable place (a new --output or --session, or a copy of the session)"
    )


def test_anything_else_is_not_a_refusal() -> None:
    assert file_system_refusal(OSError(errno.EIO, "Input/output error", "/x")) is None
    assert file_system_refusal(ValueError("no")) is None
    assert file_system_refusal(FileNotFoundError(errno.ENOENT, "No such file or directory", "/x")) is None
