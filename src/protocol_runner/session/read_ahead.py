"""The report's configurations read ahead, while the session waits for its last analyses.

Reading the configurations (decompressing every trial) is most of the report's reading time at the end.
A configuration whose analyses are journaled is final in the archive's draft (`assembly.ArchiveDraft`) but
for the attributes consolidation adds (`assembly.configuration_attrs`). Most were read already: the
analysis worker that ended a configuration's analyses read it from its units for its figures
(`early_figures.draw_ahead`) and hands it over (`offer`). Such a read is taken for the archive's group
when the units it read are the journaled units of the configuration's steps (only they write into its
group, `steps/`), in journal order (consolidation's), each the very file journaled, not written anew
since; its fields read from the group's own attributes are read again from the units' attributes with
consolidation's written over them, as HDF5 stores them. Any other configuration is read from the draft
with the report's own reader, consolidation's attributes written into it first (consolidation writes them
again, last).

At the end a configuration read ahead is used only if its archive group is the one it was read from:
the journal's units up to the read are unchanged, no unit journaled after it holds the configuration, and
its attributes are those consolidation wrote; any other configuration is read from the archive.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import h5py
import numpy as np

from ..archive.h5util import put_attrs
from ..archive.units import UnitRecord
from ..protocol.plan import Plan
from .assembly import ArchiveDraft, configuration_attrs
from .early_figures import UnitsRead, configuration_step_ids, file_identity

if TYPE_CHECKING:
    from ..report.model import Configuration


@dataclass(frozen=True)
class _Read:
    configuration: Configuration
    attrs: dict[str, Any]  # the attributes consolidation adds, as they were at the read
    records: tuple[UnitRecord, ...]  # the journal's units the configuration was read from (and before it)


class ReadAhead:
    """Configurations read ahead (from the workers' reads, or the draft of `ahead`), checked against the
    archive at the end (`known`)."""

    def __init__(self, plan: Plan, ahead: ArchiveDraft) -> None:
        self.plan = plan
        self.ahead = ahead
        self.read: dict[str, _Read] = {}
        self.offered: dict[str, UnitsRead] = {}  # the workers' reads, not checked yet

    def offer(self, read: UnitsRead) -> None:
        """Keep a configuration an analysis worker read from its units (those units journaled) for `update`."""
        self.offered[read.configuration.name] = read

    def update(self, *, draft: bool = True) -> None:
        """Take the configurations whose analyses are journaled and that are not read yet: from the workers'
        reads where they are the archive's, else (with `draft`, the draft merged up to now) from the draft."""
        attrs = configuration_attrs(self.plan, self.ahead.journal.units)
        todo = [n for n, a in attrs.items() if a["status"] == "complete" and n not in self.read]
        if not todo:
            return
        taken = self._take_offered([n for n in todo if n in self.offered], attrs)
        if draft:
            self._read_draft([n for n in todo if n not in taken], attrs)

    def _take_offered(self, names: list[str], attrs: Mapping[str, dict[str, Any]]) -> set[str]:
        """The workers' reads of `names` taken as the archive's groups (the others are dropped)."""
        journal = self.ahead.journal
        if not names or journal.failed:  # a failed unit is consolidated after the others: none is sure
            return set()
        records = tuple(journal.units.values())
        stored = _as_stored({name: attrs[name] for name in names})
        taken: set[str] = set()
        for name in names:
            read = self.offered.pop(name)
            if stored is None or not self._is_archived(attrs[name]["key"], read, records):
                continue
            cfg = _read_only(read.configuration)
            with contextlib.suppress(Exception):  # an optimisation only: read from the draft instead
                from ..report.load_configuration import with_group_attrs

                cfg = with_group_attrs(cfg, {**read.attrs, **stored[name]})
                self.read[name] = _Read(cfg, dict(attrs[name]), records)
                taken.add(name)
        return taken

    def _is_archived(self, key: object, read: UnitsRead, records: tuple[UnitRecord, ...]) -> bool:
        """Whether `read` merged the units consolidation merges into configuration `key`'s group: the
        journaled units of its steps, in journal order, each file unchanged since it was journaled."""
        steps = set(configuration_step_ids(self.plan, key))
        own = [r for r in records if r.step_id in steps]
        if [r.file for r in own] != [file for file, _ in read.files]:
            return False
        for record, (file, identity) in zip(own, read.files, strict=True):
            try:
                st = os.stat(self.ahead.units_dir / file)
            except OSError:
                return False
            if file_identity(st) != identity or st.st_size != record.size:
                return False
        return True

    def _read_draft(self, names: list[str], attrs: Mapping[str, dict[str, Any]]) -> None:
        """Read configurations `names` from the draft with the report's reader."""
        draft = self.ahead.draft
        if draft is None or not names:
            return
        from ..report.load_configuration import read_configuration  # the report's reader (no matplotlib)

        with contextlib.suppress(Exception), h5py.File(draft.path, "r+") as f:  # an optimisation only
            for name in names:
                if f"configurations/{name}" not in f:
                    continue
                grp = f["configurations"][name]
                put_attrs(grp, "configuration", attrs[name])  # as consolidation will (again, last)
                cfg = read_configuration(name, grp)
                self.read[name] = _Read(cfg, dict(attrs[name]), self.ahead.records)

    def known(self) -> dict[str, Configuration]:
        """The configurations read ahead whose archive group is still the one they were read from."""
        journal = self.ahead.journal
        records = list(journal.units.values()) + list(journal.failed.values())
        attrs = configuration_attrs(self.plan, journal.units)
        fresh = [
            (name, read)
            for name, read in self.read.items()
            if tuple(records[: len(read.records)]) == read.records and attrs.get(name) == read.attrs
        ]
        if not fresh:
            return {}
        first = min(len(read.records) for _, read in fresh)
        held = _configurations_in(self.ahead.units_dir, records[first:])  # per unit after the first read
        if held is None:
            return {}
        out: dict[str, Configuration] = {}
        for name, read in fresh:
            if not any(name in names for names in held[len(read.records) - first :]):
                out[name] = read.configuration
        return out


def _as_stored(attrs: Mapping[str, Mapping[str, Any]]) -> dict[str, dict[str, Any]] | None:
    """Per group, the attributes `attrs` as consolidation writes them and HDF5 gives them back (written
    into a file in memory); None if they cannot be."""
    with contextlib.suppress(Exception), h5py.File("in-memory", "w", driver="core", backing_store=False) as f:
        out: dict[str, dict[str, Any]] = {}
        for name, group_attrs in attrs.items():
            grp = f.create_group(name)
            put_attrs(grp, "configuration", group_attrs)
            out[name] = {key: grp.attrs[key] for key in grp.attrs}
        return out
    return None


def _read_only(value: Any) -> Any:
    """`value` with every array in it marked read-only again, as the report's reader gives them (arrays
    come out of a worker's pickle writable); `value` itself is returned."""
    if isinstance(value, np.ndarray):
        value.flags.writeable = False
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        for field in dataclasses.fields(value):
            _read_only(getattr(value, field.name))
    elif isinstance(value, tuple):
        for item in value:
            _read_only(item)
    return value


def _configurations_in(units_dir: Path, records: list[UnitRecord]) -> list[set[str]] | None:
    """The configuration groups each unit holds; None if a unit cannot be read (none is trusted then)."""
    held: list[set[str]] = []
    for record in records:
        try:
            with h5py.File(units_dir / record.file, "r") as unit:
                held.append(set(unit.get("configurations", ())))
        except OSError:
            return None
    return held
