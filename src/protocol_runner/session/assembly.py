"""Archive assembly: the session's units and metadata consolidated into `archive.h5` (docs/archive.md)."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

from ..analysis.reference import load_reference_dataset
from ..archive.consolidate import ArchiveMeta, Draft, consolidate, draft
from ..archive.paths import configuration_name
from ..archive.units import UnitRecord, checked_unit_files
from ..protocol.loader import LoadedProtocol
from ..protocol.plan import Plan, TrialStep
from ..protocol.step_ids import step_id as make_step_id
from .journal import Journal, utc_now
from .setup import SessionInfo

ARCHIVE_NAME = "archive.h5"


def configuration_attrs(plan: Plan, done: Mapping[str, object]) -> dict[str, dict[str, object]]:
    """Per configuration group: its key, number of trials and status (complete, partial, not run)."""
    out: dict[str, dict[str, object]] = {}
    for step in plan.steps:
        if not isinstance(step, TrialStep):
            continue
        name = configuration_name(step.configuration)
        entry = out.setdefault(name, {"key": step.configuration, "n_trials": 0, "_any": False})
        if step.brace == "on":
            entry["n_trials"] = int(entry["n_trials"]) + 1  # type: ignore[call-overload]
        entry["_any"] = bool(entry["_any"]) or step.id in done
    for entry in out.values():
        key = int(entry["key"])  # type: ignore[call-overload]
        fit, process = make_step_id("fit", key=key), make_step_id("process", key=key)
        fitted = fit in done or (process in done and fit not in plan._index)
        entry["status"] = "complete" if fitted else ("partial" if entry.pop("_any") else "not run")
        entry.pop("_any", None)
    return out


class ArchiveDraft:
    """The session's journaled units merged into `archive.h5.partial` ahead of its end (while it waits for
    its last analyses), so that consolidation only adds the units journaled since. Each unit is checked
    against its journaled sha256 before it is merged, as consolidation would; a draft whose units are not
    the first of the journal's at the end (a unit redone, one failed) is left aside and consolidation starts
    afresh. Any error here only drops the draft: consolidation meets it again and reports it."""

    def __init__(self, session_dir: Path, journal: Journal) -> None:
        self.units_dir = session_dir / "units"
        self.archive = session_dir / ARCHIVE_NAME
        self.journal = journal
        self.records: tuple[UnitRecord, ...] = ()
        self.draft: Draft | None = None

    def update(self) -> None:
        """Merge the units journaled since the last update into the draft."""
        records = tuple(self.journal.units.values())
        if self.journal.failed or records == self.records:
            return
        previous = self.draft if records[: len(self.records)] == self.records else None
        new = records[len(self.records) :] if previous is not None else records
        self.draft, self.records = None, ()
        try:
            files = (previous.files if previous is not None else ()) + tuple(
                checked_unit_files(self.units_dir, new)
            )
            self.draft, self.records = draft(self.archive, files, previous), records
        except Exception:  # an optimisation: consolidation does it all and meets the error itself
            return

    def lead(self, records: list[UnitRecord]) -> tuple[Draft | None, list[Path]]:
        """The draft (if its units are the first of `records`) and the files of the records after it."""
        n = len(self.records)
        if self.draft is None or tuple(records[:n]) != self.records:
            return None, []
        return self.draft, list(self.draft.files)


def consolidate_session(
    session_dir: Path,
    info: SessionInfo,
    loaded: LoadedProtocol,
    plan: Plan,
    journal: Journal,
    status: str,
    ahead: ArchiveDraft | None = None,
) -> Path:
    """The session's finished (and failed-but-kept) units, checked, into `archive.h5` with the session's
    metadata; the units already merged in `ahead`'s draft are not read again."""
    records = list(journal.units.values()) + list(journal.failed.values())
    started, files = ahead.lead(records) if ahead is not None else (None, [])
    done = len(ahead.records) if ahead is not None and started is not None else 0
    files += checked_unit_files(session_dir / "units", records[done:])
    root = {
        "protocol_name": info.protocol_name,
        "protocol_sha256": loaded.sha256,
        "rig_sha256": loaded.rig_source.sha256,
        "mode": info.mode,
        "seed": int(info.seed),
        "created_utc": info.created_utc,
        "finished_utc": utc_now(),
        "status": status,
        "joint": ",".join(loaded.protocol.driven_joints),
    }
    meta = ArchiveMeta(
        root=root,
        protocol_text=loaded.text,
        protocol_filename=loaded.path.name,
        rig_text=loaded.rig_source.text,
        rig_filename=loaded.rig_source.shown,
        plan_json=json.dumps(plan.to_json()),
        only=info.only,
        events=tuple(json.dumps(e.to_json()) for e in journal.events),
        configuration_attrs=configuration_attrs(plan, journal.units),
        reference=reference_dataset(loaded),
    )
    return consolidate(session_dir / ARCHIVE_NAME, files, meta, started)


def reference_dataset(loaded: LoadedProtocol) -> tuple[str, str, object, object] | None:
    """The protocol's EMU reference dataset (§5.6), copied into the archive so the report needs nothing else."""
    rel = loaded.protocol.report.reference_dataset
    if rel is None:
        return None
    ref = load_reference_dataset(loaded.base_dir / rel)
    return (Path(rel).stem, rel, ref.angle_deg, ref.torque_nm)
