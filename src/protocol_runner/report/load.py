"""Read an archive (docs/archive.md) into a `ReportData`, with clear errors for anything that is not one.

An unfinished session's archive loads normally (the report marks it incomplete). Each configuration group
is read per joint (`archive.paths.joint_groups`); the checks are `archive/verify.py`'s.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from protocol_runner.analysis.reference import ReferenceDataset
from protocol_runner.archive.model_results import strings
from protocol_runner.archive.paths import JOINTS, joint_groups
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
    attr_bool,
    attr_float,
    attr_floats,
    attr_int,
    attr_str,
    decimate_for_plot,
    decode,
    float_ds,
    read_only,
    read_record,
    scalar_str,
    subgroups,
)
from protocol_runner.report.headline import peak_of, range_of, slope_of
from protocol_runner.report.model import (
    BoucWenFit,
    BraceOffMatch,
    CalibrationCheck,
    ChecklistAnswer,
    Configuration,
    ElementFit,
    JointsTotal,
    ProcessedTrial,
    Recording,
    ReportData,
    SessionEvent,
    SessionInfo,
    Trial,
)
from protocol_runner.report.parallel import map_in_processes
from protocol_runner.report.settings_view import elements_from_json, settings_from_attrs


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


def _read_recording(joint: h5py.Group, shared: h5py.Group) -> Recording:
    """One joint's recording: its own group `joint` (the brace group itself for a single-joint archive),
    with the time base and the output loop's lateness of the trial's `shared` brace group where the joint's
    group does not repeat them."""
    given: dict[str, Any] = {
        name: decimate_for_plot(float_ds(shared, name))
        for name in ("time_s", "command_time_s")
        if name not in joint
    }
    if "tick_lateness_p99_s" not in joint.attrs:
        given["tick_lateness_p99_s"] = attr_float(shared.attrs, "tick_lateness_p99_s")
    return read_record(Recording, joint, **given)


def _trial_numbers(*trials: h5py.Group | None) -> list[tuple[int, str]]:
    """(number, name) of every trial group (a name of digits) under any of `trials`, in number order."""
    return sorted({(int(name), name) for group in trials for name in group or () if name.isdecimal()})


def read_configuration(
    name: str, grp: h5py.Group, archive_joints: str
) -> tuple[list[Configuration], JointsTotal | None]:
    """Configuration group `grp` (`name`) as one `Configuration` per joint, in channel order, and the energy
    of all its joints together when it drives several. `archive_joints` is the root attribute `joint`: it
    names the joint of a group written without a `joints/` level (`archive.paths.joint_groups`)."""
    parts: list[tuple[str, h5py.Group | None]] = list(joint_groups(grp, archive_joints))
    if JOINTS not in grp and JOINTS in grp.attrs:  # several joints, none processed yet: their recordings
        parts = [(str(j), None) for j in decode(np.atleast_1d(grp.attrs[JOINTS]))]
    configs = [_read_joint(name, grp, joint, results, archive_joints) for joint, results in parts]
    total = None
    if "total_energy_loss_j" in grp and len(configs) > 1:  # one joint: its own energy is the total
        energy = float_ds(grp, "total_energy_loss_j")
        total = JointsTotal(
            key=configs[0].key,
            energy_loss_j=read_only(energy),
            energy_cycle_trial=read_only(_cycle_trials(grp, "total_energy_cycle_trial", energy.size)),
        )
    return configs, total


def _cycle_trials(grp: h5py.Group, name: str, n_cycles: int) -> np.ndarray:
    """The trial of each cycle (dataset `name`), zeros when it does not match the `n_cycles` energies."""
    cycle_trial = float_ds(grp, name)
    return cycle_trial if cycle_trial.size == n_cycles else np.zeros(n_cycles)


def _read_joint(
    name: str, grp: h5py.Group, joint: str, results: h5py.Group | None, archive_joints: str
) -> Configuration:
    """Joint `joint`'s part of configuration group `grp`: its recordings from the trial groups `grp/trials`,
    its processing from `results` (`grp/joints/<joint>`, or `grp` itself for a single-joint archive; None
    before it is processed)."""
    trials: list[Trial] = []
    angles: list[np.ndarray] = []
    torques: list[np.ndarray] = []
    raw_loaded = False
    trajectory_json = ""
    raw_trials = grp.get("trials")
    processed_trials = results.get("trials") if results is not None else None
    for number, tname in _trial_numbers(raw_trials, processed_trials):
        tgrp = raw_trials.get(tname) if raw_trials is not None else None
        sides = {
            side: part
            for side in ("brace_on", "brace_off")
            if tgrp is not None and side in tgrp
            if (part := dict(joint_groups(tgrp[side], archive_joints)).get(joint)) is not None
        }
        on = off = None
        # Only the first recorded trial's raw data is plotted (angle/torque vs time): reading and
        # decompressing the others would dominate the report's regeneration time.
        if sides and not raw_loaded:
            assert tgrp is not None
            if "brace_on" in sides:
                trajectory_json = attr_str(sides["brace_on"].attrs, "trajectory")
                on = _read_recording(sides["brace_on"], tgrp["brace_on"])
            if "brace_off" in sides:
                off = _read_recording(sides["brace_off"], tgrp["brace_off"])
            raw_loaded = True
        ptrial = processed_trials.get(tname) if processed_trials is not None else None
        pgrp = ptrial.get("processed") if ptrial is not None else None
        processed = None
        if pgrp is not None:
            angle = float_ds(pgrp, "angle_deg")
            torque = float_ds(pgrp, "brace_torque_nm")
            n = min(angle.size, torque.size)
            angle, torque = angle[:n], torque[:n]
            angles.append(angle)
            torques.append(torque)
            processed = ProcessedTrial(
                angle_deg=decimate_for_plot(angle),
                brace_torque_nm=decimate_for_plot(torque),
                subtraction=attr_str(pgrp.attrs, "subtraction", "equal_angle"),
                filter_text=_filter_text(pgrp.attrs),
                range_deg=range_of(angle, torque),
                slope_nm_per_deg=slope_of(angle, torque),
                peak_nm=peak_of(angle, torque),
            )
        trials.append(
            Trial(
                number=number,
                brace_on=on,
                brace_off=off,
                processed=processed,
                recorded=bool(sides),
                match=brace_off_match(sides.get("brace_off"), pgrp),
            )
        )
    angle_min, angle_max = _angle_span(angles, torques)
    fits = results if results is not None else {}
    energy = float_ds(results, "energy_loss_j") if results is not None else read_only(np.empty(0))
    cycle_trial = _cycle_trials(results, "energy_cycle_trial", energy.size) if results is not None else energy
    attrs = grp.attrs
    digits = "".join(ch for ch in name if ch.isdigit())
    return Configuration(
        name=name,
        key=attr_int(attrs, "key", int(digits) if digits else 0),
        joint=joint,
        run=attr_int(attrs, "run", 0),
        set_name=attr_str(attrs, "set"),
        condition=attr_str(attrs, "condition"),
        profile=attr_str(attrs, "profile"),
        status=attr_str(attrs, "status", "complete" if trials else "not run"),
        n_trials_planned=attr_int(attrs, "n_trials", len(trials)),
        settings=settings_from_attrs(attrs, f"configuration {name}"),
        trials=tuple(trials),
        energy_loss_j=read_only(energy),
        energy_cycle_trial=read_only(cycle_trial),
        bouc_wen=_read_bouc_wen(fits["fits/bouc_wen"]) if "fits/bouc_wen" in fits else None,
        element_fit=_read_element_fit(fits["fits/elements"], name) if "fits/elements" in fits else None,
        angle_min_deg=angle_min,
        angle_max_deg=angle_max,
        trajectory_json=trajectory_json,
    )


def brace_off_match(brace_off: h5py.Group | None, processed: h5py.Group | None) -> BraceOffMatch:
    """How well one joint's brace-off twin matched its trial: the kept scaling run's error and the runs
    (`scaling/` of the joint's brace-off group `brace_off`), whether it converged, and the clipped fraction
    (1 - the joint's `processed` @coverage). The report's per-trial table and trials.csv both read it
    here."""
    error: float | None = None
    runs: int | None = None
    converged: bool | None = None
    if brace_off is not None and "scaling" in brace_off and "range_error_deg" in brace_off["scaling"]:
        g = brace_off["scaling"]
        errors = np.asarray(g["range_error_deg"][()], dtype=float)
        kept = attr_int(g.attrs, "kept_iteration", int(np.argmin(errors)) + 1)
        error, runs = float(errors[kept - 1]), int(errors.size)
        converged = attr_bool(g.attrs, "converged", False)
    clipped: float | None = None
    if processed is not None and "coverage" in processed.attrs:
        clipped = 1.0 - attr_float(processed.attrs, "coverage")
    return BraceOffMatch(error, runs, converged, clipped)


def _angle_span(angles: list[np.ndarray], torques: list[np.ndarray]) -> tuple[float, float]:
    """The lowest and highest processed angle reached (deg) over the samples with a finite angle and torque;
    NaN with fewer than two such samples."""
    reached = [a[np.isfinite(a) & np.isfinite(t)] for a, t in zip(angles, torques, strict=True)]
    reached = [a for a in reached if a.size]
    if sum(a.size for a in reached) < 2:
        return math.nan, math.nan
    return min(float(a.min()) for a in reached), max(float(a.max()) for a in reached)


def _read_bouc_wen(grp: h5py.Group) -> BoucWenFit:
    models = grp.parent.get("models")
    if not isinstance(models, h5py.Group):
        return read_record(BoucWenFit, grp, parameter_identified=(), functionals=())
    values = [
        np.atleast_1d(np.asarray(models.attrs.get(k, []), dtype=np.float64))
        for k in ("functional_value", "functional_ci95_low", "functional_ci95_high")
    ]
    functionals = tuple(
        (name, unit, float(v), float(lo), float(hi))
        for name, unit, v, lo, hi in zip(
            strings(models, "functional"), strings(models, "functional_unit"), *values, strict=True
        )
    )
    flags = np.atleast_1d(np.asarray(models.attrs.get("bouc_wen_identified", []), dtype=np.int64))
    return read_record(
        BoucWenFit, grp, parameter_identified=tuple(bool(v) for v in flags), functionals=functionals
    )


def _filter_text(attrs: h5py.AttributeManager) -> str:
    """The processing filter as a reader wants it: type, order, cut-off in Hz ("" when not recorded)."""
    hz = attr_float(attrs, "filter_cutoff_hz")
    if not math.isfinite(hz):
        return ""
    kind = attr_str(attrs, "filter_type", "low-pass").capitalize()
    return f"{kind} low-pass, order {attr_int(attrs, 'filter_order', 0)}, cut-off {hz:.1f} Hz, zero-phase"


def _read_element_fit(grp: h5py.Group, name: str) -> ElementFit:
    a = grp.attrs
    parameters = tuple(
        (key, attr_float(a, key)) for key in sorted(a.keys()) if "." in key and not key.startswith(".")
    )
    elements_text = attr_str(a, "elements_json", "[]")
    return read_record(
        ElementFit,
        grp,
        applicable=attr_bool(a, "applicable", True),
        parameters=parameters,
        elements=elements_from_json(elements_text, f"configuration {name}: fits/elements"),
    )
