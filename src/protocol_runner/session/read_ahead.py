"""The report's configurations read from the archive's draft while the session waits for its last analyses.

Reading the configurations (decompressing every trial) is most of the report's reading time at the end.
A configuration whose analyses are journaled is final in the draft (`assembly.ArchiveDraft`) but for the
attributes consolidation adds (`assembly.configuration_attrs`): they are written into the draft too (the
consolidation writes them again, last) and the configuration is read from it with the report's own reader.
At the end a configuration read ahead is used only if its archive group is the one it was read from:
the journal's units up to the read are unchanged, no unit journaled after it holds the configuration, and
its attributes are those consolidation wrote; any other configuration is read from the archive.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import h5py

from ..archive.h5util import put_attrs
from ..archive.units import UnitRecord
from ..protocol.plan import Plan
from .assembly import ArchiveDraft, configuration_attrs

if TYPE_CHECKING:
    from ..report.model import Configuration


@dataclass(frozen=True)
class _Read:
    configuration: Configuration
    attrs: dict[str, Any]  # the attributes consolidation adds, as written before the read
    records: tuple[UnitRecord, ...]  # the draft's units when it was read


class ReadAhead:
    """Configurations read from the draft of `ahead`, checked against the archive at the end (`known`)."""

    def __init__(self, plan: Plan, ahead: ArchiveDraft) -> None:
        self.plan = plan
        self.ahead = ahead
        self.read: dict[str, _Read] = {}

    def update(self) -> None:
        """Read the configurations whose analyses are in the draft and that are not read yet."""
        draft = self.ahead.draft
        if draft is None:
            return
        attrs = configuration_attrs(self.plan, self.ahead.journal.units)
        todo = [n for n, a in attrs.items() if a["status"] == "complete" and n not in self.read]
        if not todo:
            return
        from ..report.load_configuration import read_configuration  # the report's reader (no matplotlib)

        with contextlib.suppress(Exception), h5py.File(draft.path, "r+") as f:  # an optimisation only
            for name in todo:
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
