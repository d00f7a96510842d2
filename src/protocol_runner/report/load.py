"""Read an archive (docs/archive.md) into a `ReportData`, with clear errors for anything that is not one.

An unfinished session's archive loads normally (the report marks it incomplete). The session-wide groups
are read here, each configuration by `load_configuration.py`; the checks are `archive/verify.py`'s.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import h5py

from protocol_runner.analysis.reference import ReferenceDataset
from protocol_runner.archive.paths import joint_groups
from protocol_runner.archive.verify import (
    Checker,
    check_root,
    corrupt,
    require_hdf5,
    resolve_archive,
)
from protocol_runner.errors import InvalidInput
from protocol_runner.protocol.plan_steps import Comparison
from protocol_runner.report.declared import declared_count
from protocol_runner.report.h5read import (
    MAX_PLOT_POINTS,
    attr_floats,
    attr_int,
    attr_str,
    decimate_for_plot,
    decode,
    float_ds,
    read_record,
    scalar_str,
    subgroups,
)
from protocol_runner.report.load_configuration import read_configuration
from protocol_runner.report.model import (
    CalibrationCheck,
    ChecklistAnswer,
    Configuration,
    JointsTotal,
    ReportData,
    SessionEvent,
    SessionInfo,
)
from protocol_runner.report.parallel import map_in_processes


def load_report_data(
    path: Path,
    *,
    workers: int | None = None,
    verify: bool = True,
) -> ReportData:
    """Read the archive at `path` (a file, or a session directory holding `archive.h5`).

    `workers` > 1 reads the configurations on that many worker processes (decompressing a full
    campaign's trials is most of the load time); None picks 2 for large archives on a multi-core machine.
    Raises `InvalidInput`, naming the file and what is wrong, when it is missing, not HDF5, truncated or
    corrupt, not a protocol-runner archive (no root attribute `protocol_sha256`), lacks the
    `/configurations` group, or holds a dataset outside the layout's bounds or a dataset or attribute
    whose checksum does not match (archive/verify.py): every one is checked before the report uses
    anything. `verify=False` checks nothing: only for an archive this process has just consolidated from
    units whose sha256 it checked against the journal (the session's own report).
    """
    archive = resolve_archive(Path(path))
    require_hdf5(archive)
    try:
        with h5py.File(archive, "r") as h5:
            names = check_root(h5, archive)
        # the file is closed before the workers start: HDF5 handles must not be shared with a forked process
        configurations, totals = _load_configurations(archive, names, workers, verify)
        with h5py.File(archive, "r") as h5:
            if verify:  # the root's and every other group's attributes and datasets (configurations: above)
                checker = Checker.of(h5, archive)
                checker.check_tree(h5, skip=("configurations",))
                checker.check_attributes(h5["configurations"])
            return _read(h5, archive, configurations, totals)
    except InvalidInput:
        raise
    except (OSError, KeyError, ValueError, TypeError, RuntimeError) as exc:
        raise corrupt(archive, exc) from exc


Loaded = tuple[list[Configuration], JointsTotal | None]
"""A configuration group as read: one `Configuration` per joint, and the energy of all its joints together."""


def _load_chunk(archive: Path, names: list[str], verify: bool = True) -> list[Loaded]:
    with h5py.File(archive, "r") as h5:
        checker = Checker.of(h5, archive) if verify else None
        joints = attr_str(h5.attrs, "joint")
        out = []
        for name in names:
            if checker is not None:  # all of it, read or not: damage is named
                checker.check_tree(h5["configurations"][name])
            out.append(read_configuration(name, h5["configurations"][name], joints))
        return out


def _load_configurations(
    archive: Path, names: list[str], workers: int | None, verify: bool
) -> tuple[tuple[Configuration, ...], tuple[JointsTotal, ...]]:
    """Every configuration group's joints, in key order (and channel order within a key), and the totals."""
    if workers is None:
        workers = 2 if len(names) >= 12 and (os.cpu_count() or 1) >= 2 else 1
    loaded: list[Loaded] | None = None
    if workers > 1 and len(names) >= 2:
        loaded = map_in_processes(
            _load_one, [(archive, name, verify) for name in names], workers, chunksize=2
        )
    if loaded is None:
        loaded = _load_chunk(archive, names, verify)
    loaded.sort(key=lambda item: item[0][0].key if item[0] else item[1].key if item[1] else 0)
    configurations = tuple(cfg for configs, _ in loaded for cfg in configs)
    totals = tuple(total for _, total in loaded if total is not None)
    return configurations, totals


def _load_one(item: tuple[Path, str, bool]) -> Loaded:
    archive, name, verify = item
    return _load_chunk(archive, [name], verify)[0]


def _read(
    h5: h5py.File,
    archive: Path,
    configurations: tuple[Configuration, ...],
    totals: tuple[JointsTotal, ...],
) -> ReportData:
    session = _read_session(h5, archive)
    comparisons = _read_comparisons(h5)
    protocol_text = scalar_str(h5["protocol"]) if "protocol" in h5 else ""
    notes: list[str] = []
    if not comparisons:
        declared = declared_count(protocol_text, ("report", "comparisons"))
        notes.append(
            f"The protocol declares {declared} comparison{'s' if declared != 1 else ''}, none made yet in "
            f"this session (status {session.status}): the report shows no cross-configuration figures."
            if declared
            else "The protocol declares no comparisons (its report section's comparisons): the report "
            "shows no cross-configuration figures."
        )
    return ReportData(
        session=session,
        configurations=configurations,
        calibration=_read_calibration(h5),
        comparisons=comparisons,
        references=_read_references(h5),
        protocol_text=protocol_text,
        notes=tuple(notes),
        joints=session.joints or tuple(dict.fromkeys(cfg.joint for cfg in configurations)),
        totals=totals,
    )


def _read_session(h5: h5py.File, archive: Path) -> SessionInfo:
    a = h5.attrs
    events: list[SessionEvent] = []
    checklists: list[ChecklistAnswer] = []
    if "session" in h5:
        sess = h5["session"]
        if "events" in sess:
            raw = decode(sess["events"][()])
            lines = raw if isinstance(raw, list) else str(raw).splitlines()
            parsed = (_parse_event(str(line)) for line in lines if str(line).strip())
            events.extend(e for e in parsed if e is not None)
        for name, grp in subgroups(sess, "checklists"):
            items_text = attr_str(grp.attrs, "items", "[]")
            try:
                items = tuple(str(x) for x in json.loads(items_text))
            except (json.JSONDecodeError, TypeError):
                items = (items_text,)
            step_id = attr_str(grp.attrs, "step_id", name.replace("__", ":"))
            checklists.append(read_record(ChecklistAnswer, grp, step_id=step_id, items=items))
    checklists.sort(key=lambda c: (c.answered_utc, c.step_id))
    only = tuple(int(v) for v in attr_floats(a, "only"))
    return SessionInfo(
        archive_path=str(archive),
        protocol_name=attr_str(a, "protocol_name", "(unnamed protocol)"),
        protocol_sha256=attr_str(a, "protocol_sha256"),
        schema_version=attr_int(a, "schema_version", 0),
        software_version=attr_str(a, "software_version", "unknown"),
        mode=attr_str(a, "mode", "unknown"),
        seed=attr_int(a, "seed", 0),
        created_utc=attr_str(a, "created_utc"),
        finished_utc=attr_str(a, "finished_utc"),
        status=attr_str(a, "status", "incomplete"),
        joint=attr_str(a, "joint"),
        only=only,
        events=tuple(events),
        checklists=tuple(checklists),
    )


def _parse_event(line: str) -> SessionEvent | None:
    """One event line; None for an event whose detail is an empty record (e.g. no referenced files)."""
    try:
        obj = json.loads(line)
    except json.JSONDecodeError:
        obj = None
    if not isinstance(obj, dict):
        return SessionEvent(t_utc="", kind="unparsed", detail=line)
    detail = _readable_detail(obj.get("detail", ""))
    if detail is None:
        return None
    return SessionEvent(t_utc=str(obj.get("t_utc", "")), kind=str(obj.get("kind", "")), detail=detail)


def _readable_detail(detail: object) -> str | None:
    """An event's detail as a reader wants it: a record (a JSON object, possibly written as a string, e.g.
    the referenced files with their sha256) as "key: value; ..." with long hashes shortened, a list joined
    by "; ", text unchanged. None when the detail is an empty record or list."""
    if isinstance(detail, str):
        text = detail.strip()
        if not text.startswith(("{", "[")):
            return detail
        try:
            detail = json.loads(text)
        except json.JSONDecodeError:
            return text
    if isinstance(detail, dict):
        if not detail:
            return None
        return "; ".join(f"{key}: {_readable_value(value)}" for key, value in sorted(detail.items()))
    if isinstance(detail, list):
        return "; ".join(_readable_value(v) for v in detail) if detail else None
    return _readable_value(detail)


def _readable_value(value: object) -> str:
    if isinstance(value, str):
        is_hash = len(value) == 64 and all(ch in "0123456789abcdef" for ch in value)
        return f"sha256 {value[:12]}…" if is_hash else value
    return json.dumps(value, sort_keys=True)


def _read_calibration(h5: h5py.File) -> tuple[CalibrationCheck, ...]:
    """Every calibration check, one per joint (a check of several joints holds one group per joint, each
    with its own verdict; the limits are the check's)."""
    archive_joints = attr_str(h5.attrs, "joint")
    checks = [
        read_record(
            CalibrationCheck,
            part,
            set_name=set_name,
            when=when,
            joint=joint,
            verdict=attr_str(part.attrs, "verdict", "unknown"),
            limits=attr_str(part.attrs, "limits", attr_str(grp.attrs, "limits")),
        )
        for set_name, set_grp in subgroups(h5, "calibration")
        for when, grp in subgroups(set_grp)
        for joint, part in joint_groups(grp, archive_joints)
    ]
    order = {"before": 0, "after": 2}
    checks.sort(key=lambda c: (c.set_name, order.get(c.when, 1), c.when))  # stable: channel order kept
    return tuple(checks)


def _read_comparisons(h5: h5py.File) -> tuple[Comparison, ...]:
    out: list[Comparison] = []
    for name, grp in subgroups(h5, "comparisons"):
        keys = tuple(int(k) for k in attr_floats(grp.attrs, "configurations"))
        out.append(
            Comparison(
                name=name,
                parameter=attr_str(grp.attrs, "parameter", name),
                section=attr_str(grp.attrs, "section"),
                title=attr_str(grp.attrs, "title", name),
                configurations=keys,
            )
        )
    out.sort(key=lambda c: (_section_key(c.section), c.name))
    return tuple(out)


def _section_key(section: str) -> tuple[int, ...]:
    """A section such as "§5.1" as numbers to sort by (999 for a part that is not one)."""
    return tuple(int(p) if p.strip().isdecimal() else 999 for p in section.replace("§", "").split("."))


def _read_references(h5: h5py.File) -> tuple[ReferenceDataset, ...]:
    out: list[ReferenceDataset] = []
    for name, grp in subgroups(h5, "reference"):
        if "angle_deg" not in grp or "torque_nm" not in grp:
            continue
        angle = float_ds(grp, "angle_deg")
        torque = float_ds(grp, "torque_nm")
        n = min(angle.size, torque.size)
        out.append(
            ReferenceDataset(
                source=attr_str(grp.attrs, "source", f"/reference/{name}"),
                title=attr_str(grp.attrs, "title", name),
                angle_deg=decimate_for_plot(angle[:n], 4 * MAX_PLOT_POINTS),
                torque_nm=decimate_for_plot(torque[:n], 4 * MAX_PLOT_POINTS),
            )
        )
    return tuple(out)
