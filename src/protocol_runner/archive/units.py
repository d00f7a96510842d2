"""Atomic unit files: one HDF5 file per finished step.

A unit is a fragment of the final archive (its groups sit at the paths they will have in `archive.h5`).
It is written to `<name>.h5.partial`, closed, fsynced, renamed to `<name>.h5`, and the directory fsynced;
only then may the caller journal it as complete, with its sha256, so that a resume can tell a complete
unit from a truncated or foreign one.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import h5py

from ..errors import InvalidInput
from .attrs import UNIT_COMPLETE, UNIT_STEP_ID
from .checksums import mark, seal_attributes, seal_missing
from .diskfull import DiskFull, is_disk_full, resume_hint
from .h5_write_errors import checked_h5_write
from .h5util import group_name


@dataclass(frozen=True)
class UnitRecord:
    step_id: str
    file: str  # name inside the units directory
    sha256: str
    size: int


def unit_path(units_dir: Path, step_id: str) -> Path:
    return units_dir / f"{group_name(step_id)}.h5"


def fsync_path(path: Path) -> None:
    """Flush a file's or a directory's entry (after a rename into it) to the disk. Windows cannot open a
    directory with `os.open` (NTFS journals the rename itself): a directory is flushed on POSIX only."""
    if os.name == "nt" and path.is_dir():
        return
    # Windows flushes only a handle opened for writing (FlushFileBuffers); POSIX any descriptor
    fd = os.open(path, os.O_RDWR if os.name == "nt" else os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_file(path: Path) -> None:
    """A unit file's flush (its own name: the fault-injection tests fail these, not the directory's)."""
    fsync_path(path)


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
        with checked_h5_write(partial), h5py.File(partial, "w") as f:  # checked: writes h5py only prints
            fill(f)
            f.attrs[UNIT_STEP_ID] = step_id
            seal_missing(f)  # datasets written without archive/h5util.py get their checksum too
            mark(f)
            f.attrs[UNIT_COMPLETE] = True
            seal_attributes(f)  # every attribute written, by whatever code, gets its checksum
        _fsync_file(partial)
        digest = sha256_of(partial)
        os.replace(partial, final)
        fsync_path(units_dir)
    except BaseException as exc:  # never leave a partial file behind: a fill's bug, a full disk, Ctrl-C
        with contextlib.suppress(OSError):
            partial.unlink()
        if isinstance(exc, OSError | RuntimeError) and is_disk_full(exc):  # HDF5: RuntimeError at close
            raise DiskFull(
                f"disk full while saving {step_id} in {units_dir}. {resume_hint(units_dir.parent)}"
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
            return bool(f.attrs.get(UNIT_COMPLETE, False)) and f.attrs.get(UNIT_STEP_ID) == record.step_id
    except (OSError, KeyError):
        return False


def checked_unit_files(units_dir: Path, records: Iterable[UnitRecord]) -> list[Path]:
    """The files of the journaled units, each checked against its journaled size and sha256 before it is
    consolidated: a unit damaged on disk since it was written is named (exit 2) instead of being copied
    into the archive; `--resume` then redoes its step."""
    files = []
    for record in records:
        path = units_dir / record.file
        if not path.is_file():
            continue  # a unit removed since: its step is redone on resume
        if path.stat().st_size != record.size or sha256_of(path) != record.sha256:
            raise InvalidInput(
                f"{path} is damaged: it no longer matches the sha256 journaled when it was written, so it is "
                f"not put into the archive. run-protocol --resume {units_dir.parent} redoes its step"
            )
        files.append(path)
    return files


def open_unit(units_dir: Path, step_id: str) -> h5py.File:
    return h5py.File(unit_path(units_dir, step_id), "r")
