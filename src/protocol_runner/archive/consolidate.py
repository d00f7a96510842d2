"""Consolidation: merge every completed unit into one self-contained `archive.h5` (docs/archive.md).

Units are fragments of the archive at their final paths; they are merged into `archive.h5.partial` as
copying them over one another in plan order would (`merge_units`), with the root provenance, `/protocol`,
`/plan`, `/session/events` and each configuration's status, then renamed. Rerunning it gives the same
archive content.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
from h5py import h5a, h5f, h5g, h5o, h5p, h5s

from .. import __version__
from .attrs import ATTRIBUTE_DIGESTS, ATTRIBUTE_MARKER, ATTRIBUTES, CHECKSUM_MARKER, FILENAME, ONLY
from .checksums import attribute_names, is_marked, mark, read_attr, seal_attributes
from .diskfull import DiskFull, is_disk_full, resume_hint
from .h5_write_errors import checked_h5_write
from .h5util import SCHEMA_VERSION, put, put_attrs, put_text
from .paths import REFERENCE
from .units import fsync_path


@dataclass(frozen=True)
class ArchiveMeta:
    """What a session adds to its units' content when it consolidates them."""

    #: the session's root attributes (docs/archive.md "Root"); the layout and software versions are added
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


#: The units' own root attributes, and their attribute checksums (the archive's are recorded from the
#: merged values, `_write`): not copied into the archive.
_UNIT_ONLY = frozenset((*ATTRIBUTES["unit"], CHECKSUM_MARKER, ATTRIBUTE_MARKER, ATTRIBUTE_DIGESTS))
_UNIT_ONLY_NAMES = frozenset(name.encode("utf-8") for name in _UNIT_ONLY)
_LCPL = h5p.create(h5p.LINK_CREATE)  # what h5py's `Group.copy` creates the copy's link with
_LCPL.set_create_intermediate_group(True)
_FAPL = h5p.create(h5p.FILE_ACCESS)  # a unit opened as `h5py.File(path, "r")` would be
_FAPL.set_libver_bounds(h5f.LIBVER_EARLIEST, h5f.LIBVER_LATEST)

# The merge works on HDF5's identifiers (h5py's low-level API): h5py's objects and lookups cost more than
# the HDF5 calls they make, and a knee session's merge visits about 1,000 groups and 3,000 attributes.


def _link_names(group: h5g.GroupID) -> list[bytes]:
    names: list[bytes] = []
    group.links.iterate(names.append)  # append returns None: iteration goes on
    return names


def _copy_attr(src: h5g.GroupID, dst: h5g.GroupID, name: bytes) -> None:
    """Give `dst` `src`'s attribute `name` (`dst` has none of that name): its HDF5 type, dataspace and
    values, as `dst.attrs[name] = src.attrs[name]` writes them for every type a unit holds."""
    attr = h5a.open(src, name)
    space = attr.get_space()
    copy = h5a.create(dst, name, attr.get_type(), space)
    if space.get_simple_extent_type() != h5s.NULL:  # an empty attribute has no values
        values, mtype = read_attr(attr)
        if values.size:
            copy.write(values, mtype=mtype)


def _merge_under(src: h5g.GroupID, dst: h5g.GroupID) -> None:
    """Add to `dst` what `src` holds and `dst` does not. Everything in `dst` came from units later in
    the plan than `src` (consolidation merges last to first), and a later unit's value wins: an attribute
    or member `dst` already has is left as it is, unread; only a group both hold is merged in turn (a
    later unit's dataset where an earlier one has a group replaces it whole)."""
    for key in attribute_names(src):
        if key not in _UNIT_ONLY_NAMES and not h5a.exists(dst, key):
            _copy_attr(src, dst, key)
    for name in _link_names(src):
        if not dst.links.exists(name):
            h5o.copy(src, name, dst, name, None, _LCPL)  # whole subtree in one call (chunks copied as stored)
            continue
        theirs = h5o.open(src, name)
        if isinstance(theirs, h5g.GroupID):
            ours = h5o.open(dst, name)
            if isinstance(ours, h5g.GroupID):
                _merge_under(theirs, ours)


def merge_units(out: h5py.Group, unit_files: Iterable[Path]) -> bool:
    """Merge the units into `out` as if each were copied over the ones before it (in plan order, a later
    unit's attribute or dataset replacing an earlier one's), by adding them last to first without
    replacing anything; whether every unit carried checksums (units written before checksums existed, in a
    session resumed across versions, did not)."""
    summed = True
    for path in reversed(list(unit_files)):
        unit = h5f.open(os.fsencode(path), h5f.ACC_RDONLY, fapl=_FAPL)
        try:
            summed = summed and is_marked(h5py.File(unit))  # the unit's identifier, as h5py's file
            _merge_under(unit, out.id)
        finally:
            unit.close()
    return summed


def consolidate(archive: Path, unit_files: Iterable[Path], meta: ArchiveMeta) -> Path:
    """Write `archive` from the units; on a full disk raise `DiskFull`, leaving the previous archive (if
    any) and no partial file behind."""
    partial = archive.with_name(archive.name + ".partial")
    try:
        with checked_h5_write(partial):  # writes h5py could only print (a full disk) fail it too
            _write(partial, list(unit_files), meta)
        fsync_path(partial)
        os.replace(partial, archive)
        fsync_path(archive.parent)
    except (OSError, RuntimeError) as exc:  # HDF5 reports some refused writes as RuntimeError
        partial.unlink(missing_ok=True)
        if is_disk_full(exc):
            raise DiskFull(f"disk full while writing {archive}. {resume_hint(archive.parent)}") from None
        raise
    return archive


def _write(partial: Path, unit_files: list[Path], meta: ArchiveMeta) -> None:
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
        put_text(out.require_group("session"), "events", list(meta.events))
        if meta.reference is not None:
            name, source, angle_deg, torque_nm = meta.reference
            ref = out.require_group(f"{REFERENCE}/{name}")
            put(ref, "angle_deg", angle_deg, "deg")
            put(ref, "torque_nm", torque_nm, "N*m")
            put_attrs(ref, "reference", {"source": source, "title": name})
        configs = out.require_group("configurations")
        for name, attrs in meta.configuration_attrs.items():
            put_attrs(configs.require_group(name), "configuration", attrs)
        if summed:
            mark(out)  # every dataset, copied from a unit or written here, carries its checksum
        # every attribute's checksum, from the values merged from the units (each checked against the sha256
        # its journal recorded before it was merged) and written here
        seal_attributes(out)
