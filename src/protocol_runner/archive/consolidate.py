"""Consolidation: merge every completed unit into one self-contained `archive.h5` (docs/archive.md).

Units are fragments of the archive at their final paths; consolidation copies them in plan order into
`archive.h5.partial`, adds the root provenance, `/protocol`, `/plan`, `/session/events` and each
configuration's status, then renames atomically. Rerunning it gives the same archive content.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from .. import __version__
from .attrs import ATTRIBUTES, FILENAME, ONLY
from .checksums import MARKER_ATTR, is_marked, mark
from .diskfull import DiskFull, is_disk_full, resume_hint
from .h5util import SCHEMA_VERSION, put, put_attrs, put_lines, put_text
from .units import _fsync_dir, _fsync_file


@dataclass(frozen=True)
class ArchiveMeta:
    """What a session adds to its units' content when it consolidates them."""

    #: the session's root attributes (docs/archive.md "Root": `protocol_name`, `protocol_sha256`, `mode`,
    #: `seed`, `created_utc`, `finished_utc`, `status`, `joint`); the layout and software versions are added
    root: Mapping[str, Any]
    protocol_text: str
    protocol_filename: str
    plan_json: str
    only: tuple[int, ...]
    events: tuple[str, ...]
    configuration_attrs: Mapping[str, Mapping[str, Any]]  # group name -> attrs (incl. status)
    # the rig file the protocol was checked against, exactly as read, and its name (`rigs/rsst.yaml`)
    rig_text: str = ""
    rig_filename: str = ""
    # the EMU comparison's reference data (§5.6), if the protocol names one: (name, source, angle, torque)
    reference: tuple[str, str, Any, Any] | None = None


def _same(a: object, b: object) -> bool:
    """Whether attribute values `a` and `b` are the same value of the same type (arrays: dtype and items)."""
    if type(a) is not type(b):
        return False
    if isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray)
        return a.dtype == b.dtype and a.shape == b.shape and bool(np.array_equal(a, b))
    return bool(a == b)


def _merge(src: h5py.Group, dst: h5py.Group, written: dict[str, dict[str, object]] | None = None) -> None:
    """Merge `src` into `dst`. `written` remembers the attributes already set on each destination group
    during this consolidation (every trial unit repeats its configuration's attributes): an attribute whose
    value is already there is not rewritten. The result is the same as rewriting it."""
    if written is None:
        written = {}
    seen = written.setdefault(dst.name, {})
    for key, value in src.attrs.items():
        if key in ATTRIBUTES["unit"] or key == MARKER_ATTR:
            continue
        if key in seen and _same(seen[key], value):
            continue
        dst.attrs[key] = value
        seen[key] = value
    for name, obj in src.items():
        if isinstance(obj, h5py.Group):
            if name in dst:
                _merge(obj, dst[name], written)
            else:
                src.copy(obj, dst, name=name)  # whole subtree in one HDF5 call (chunks copied as stored)
        else:
            if name in dst:
                del dst[name]
            src.copy(obj, dst, name=name)


def merge_units(out: h5py.Group, unit_files: Iterable[Path]) -> bool:
    """Merge the units (in order) into `out`, as consolidation does; whether every unit carried checksums."""
    written: dict[str, dict[str, object]] = {}
    summed = True  # units written before checksums existed (a session resumed across versions): not
    for path in unit_files:
        with h5py.File(path, "r") as unit:
            summed = summed and is_marked(unit)
            _merge(unit, out, written)
    return summed


def consolidate(archive: Path, unit_files: Iterable[Path], meta: ArchiveMeta) -> Path:
    """Write `archive` from the units; on a full disk raise `DiskFull`, leaving the previous archive (if
    any) and no partial file behind."""
    partial = archive.with_name(archive.name + ".partial")
    try:
        _write(partial, unit_files, meta)
        _fsync_file(partial)
        os.replace(partial, archive)
        _fsync_dir(archive.parent)
    except OSError as exc:
        partial.unlink(missing_ok=True)
        if is_disk_full(exc):
            raise DiskFull(f"disk full while writing {archive}. {resume_hint(archive.parent)}") from None
        raise
    return archive


def _write(partial: Path, unit_files: Iterable[Path], meta: ArchiveMeta) -> None:
    partial.unlink(missing_ok=True)
    with h5py.File(partial, "w") as out:
        summed = merge_units(out, unit_files)
        put_attrs(
            out, "root", {**meta.root, "schema_version": SCHEMA_VERSION, "software_version": __version__}
        )
        out.attrs[ONLY] = list(meta.only) if meta.only else []  # an empty list too (put_attrs skips none)
        ds = put_text(out, "protocol", meta.protocol_text)
        put_attrs(ds, "protocol", {FILENAME: meta.protocol_filename})
        if meta.rig_text:
            ds = put_text(out, "rig", meta.rig_text)
            put_attrs(ds, "rig", {FILENAME: meta.rig_filename})
        put_text(out, "plan", meta.plan_json)
        put_lines(out.require_group("session"), "events", list(meta.events))
        if meta.reference is not None:
            name, source, angle_deg, torque_nm = meta.reference
            ref = out.require_group(f"reference/{name}")
            put(ref, "angle_deg", angle_deg, "deg")
            put(ref, "torque_nm", torque_nm, "N*m")
            put_attrs(ref, "reference", {"source": source, "title": name})
        configs = out.require_group("configurations")
        for name, attrs in meta.configuration_attrs.items():
            put_attrs(configs.require_group(name), "configuration", attrs)
        if summed:
            mark(out)  # every dataset, copied from a unit or written here, carries its checksum
