"""Atomic unit files: one HDF5 file per finished step (DESIGN.md "Reliability rules").

A unit is a fragment of the final archive (its groups sit at the paths they will have in `archive.h5`).
It is written to `<name>.h5.partial`, closed, fsynced, renamed to `<name>.h5`, and the directory fsynced;
only then may the caller journal it as complete. Its sha256 is returned so a resume can tell a complete
unit from a truncated or foreign one. "The file exists" never means "complete".
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import h5py

from ..errors import EXIT_INTERRUPTED, UserError
from .h5util import group_name

COMPLETE_ATTR = "unit_complete"


class DiskFull(UserError):
    """No space left while writing a unit: nothing completed is lost; free space and --resume."""

    exit_code = EXIT_INTERRUPTED


@dataclass(frozen=True)
class UnitRecord:
    step_id: str
    file: str  # name inside the units directory
    sha256: str
    size: int


def unit_path(units_dir: Path, step_id: str) -> Path:
    return units_dir / f"{group_name(step_id)}.h5"


def _fsync_file(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_dir(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def sha256_of(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def write_unit(units_dir: Path, step_id: str, fill: Callable[[h5py.File], None]) -> UnitRecord:
    """Write a unit atomically; `fill(f)` puts the step's groups and datasets into the open file."""
    units_dir.mkdir(parents=True, exist_ok=True)
    final = unit_path(units_dir, step_id)
    partial = final.with_name(final.name + ".partial")
    with contextlib.suppress(FileNotFoundError):
        partial.unlink()
    try:
        with h5py.File(partial, "w") as f:
            fill(f)
            f.attrs["unit_step_id"] = step_id
            f.attrs[COMPLETE_ATTR] = True
        _fsync_file(partial)
        digest = sha256_of(partial)
        os.replace(partial, final)
        _fsync_dir(units_dir)
    except OSError as exc:
        with contextlib.suppress(OSError):
            partial.unlink()
        if exc.errno == errno.ENOSPC or "No space left" in str(exc):
            raise DiskFull(
                f"disk full while saving {step_id} in {units_dir}: every step finished before it is kept. "
                "Free some space, then continue with: run-protocol --resume "
                f"{units_dir.parent}"
            ) from None
        raise
    return UnitRecord(step_id=step_id, file=final.name, sha256=digest, size=final.stat().st_size)


def unit_is_complete(units_dir: Path, record: UnitRecord) -> bool:
    """True when the unit file exists, has the journaled sha256 and opens as a complete HDF5 unit."""
    path = units_dir / record.file
    if not path.is_file() or path.stat().st_size != record.size:
        return False
    if sha256_of(path) != record.sha256:
        return False
    try:
        with h5py.File(path, "r") as f:
            return bool(f.attrs.get(COMPLETE_ATTR, False)) and f.attrs.get("unit_step_id") == record.step_id
    except (OSError, KeyError):
        return False


def open_unit(units_dir: Path, step_id: str) -> h5py.File:
    return h5py.File(unit_path(units_dir, step_id), "r")
