"""Archive assembly: the session's units and metadata consolidated into `archive.h5` (docs/archive.md)."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

from ..analysis.reference import load_reference_dataset
from ..archive.consolidate import ArchiveMeta, consolidate
from ..archive.paths import configuration_name
from ..archive.units import checked_unit_files
from ..protocol.loaded import LoadedProtocol
from ..protocol.plan_steps import Plan, TrialStep
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


def consolidate_session(
    session_dir: Path,
    info: SessionInfo,
    loaded: LoadedProtocol,
    plan: Plan,
    journal: Journal,
    status: str,
) -> Path:
    """The session's finished (and failed-but-kept) units, checked, into `archive.h5` with the session's
    metadata."""
    records = list(journal.units.values()) + list(journal.failed.values())
    files = checked_unit_files(session_dir / "units", records)
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
    return consolidate(session_dir / ARCHIVE_NAME, files, meta)


def reference_dataset(loaded: LoadedProtocol) -> tuple[str, str, object, object] | None:
    """The protocol's EMU reference dataset (§5.6), copied into the archive so the report needs nothing else."""
    rel = loaded.protocol.report.reference_dataset
    if rel is None:
        return None
    ref = load_reference_dataset(loaded.base_dir / rel)
    return (Path(rel).stem, rel, ref.angle_deg, ref.torque_nm)
