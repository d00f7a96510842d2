"""The session-wide parts of an archive, for the report: session information and events, calibration
checks, comparisons and reference datasets (docs/archive.md)."""

from __future__ import annotations

import json
from pathlib import Path

import h5py

from protocol_runner.analysis.reference import ReferenceDataset
from protocol_runner.archive.paths import joint_groups
from protocol_runner.protocol.plan_steps import Comparison
from protocol_runner.report.h5read import (
    MAX_PLOT_POINTS,
    attr_floats,
    attr_int,
    attr_str,
    decimate_for_plot,
    decode,
    float_ds,
    read_record,
    subgroups,
)
from protocol_runner.report.model import CalibrationCheck, ChecklistAnswer, SessionEvent, SessionInfo


def read_session(h5: h5py.File, archive: Path) -> SessionInfo:
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
        return SessionEvent(t_utc="", kind="unparsed", detail=line)
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


def read_calibration(h5: h5py.File) -> tuple[CalibrationCheck, ...]:
    """Every calibration check, one per joint (`archive.paths.joint_groups`: a check of several joints holds
    one group per joint, each with its own verdict; the limits are the check's)."""
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


def read_comparisons(h5: h5py.File) -> tuple[Comparison, ...]:
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
    parts: list[int] = []
    for piece in section.replace("§", "").split("."):
        try:
            parts.append(int(piece))
        except ValueError:
            parts.append(999)
    return tuple(parts) if parts else (999,)


def read_references(h5: h5py.File) -> tuple[ReferenceDataset, ...]:
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
