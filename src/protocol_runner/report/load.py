"""Read an archive (docs/archive.md) into a `ReportData`, with clear errors for anything that is not one.

`load_report_data(path)` accepts `archive.h5` or the session directory holding it. A corrupt, truncated
or foreign file, or a dataset outside the layout's bounds or not matching its checksum, raises `protocol_runner.errors.InvalidInput` naming the file and what is wrong; an
archive of an unfinished session (root `status` other than "complete") loads normally and the report
marks it incomplete.

Also here: `load_reference_dataset(path)` for the EMU comparison of thesis §5.6 (CSV or MATLAB .mat with
an angle and a torque column; format in docs/report.md).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from protocol_runner.analysis.reference import load_reference_dataset as load_reference_dataset
from protocol_runner.archive.verify import (
    Checker,
    check_root,
    corrupt,
    require_hdf5,
    resolve_archive,
)
from protocol_runner.archive.verify import validate_archive as validate_archive  # its former home
from protocol_runner.errors import InvalidInput
from protocol_runner.report.model import (
    BoucWenFit,
    CalibrationCheck,
    ChecklistAnswer,
    Comparison,
    Configuration,
    ProcessedTrial,
    Recording,
    ReferenceDataset,
    ReportData,
    SessionEvent,
    SessionInfo,
    SpringFit,
    Trial,
)
from protocol_runner.report.parallel import map_in_processes

#: Most points drawn per line: the processed data is low-pass filtered (thesis §4.4), so ~250 points per
#: sinusoid cycle of a 65 s, 8-cycle trial still draw it exactly at report resolution.
MAX_PLOT_POINTS = 2000

#: The comparisons of thesis Chapter 5 (matrix keys of Appendix A, Table 5), used when the archive has no
#: `/comparisons` groups: (name, parameter, section, title, keys).
THESIS_COMPARISONS: tuple[tuple[str, str, str, str, tuple[int, ...]], ...] = (
    ("speed", "speed", "5.1", "Speed of displacement", (10, 11)),
    ("brace_rom", "brace_rom", "5.2", "Limitation of the brace range of motion", (1, 2, 3)),
    ("friction", "friction", "5.3", "Brake friction", (4, 5, 6, 7)),
    ("stiffness", "stiffness", "5.4", "Spring stiffness", (17, 20, 14, 23)),
    ("preload", "preload", "5.5", "Spring preload", (8, 3, 9)),
    ("robot_rom", "robot_rom", "5.7.2", "Range of motion of the trajectory", (12, 13, 14)),
    ("emu", "emu", "5.6", "EMU comparison", (24, 25, 26, 27, 28)),
)


# Configuration attributes shown as the row of the test matrix, not settings.
_IDENTITY_ATTRS = {"key", "run", "set", "condition", "profile", "status", "n_trials"}


def load_report_data(path: Path, *, workers: int | None = None) -> ReportData:
    """Read the archive at `path` (a file, or a session directory holding `archive.h5`).

    `workers` > 1 reads the configurations on that many forked processes (decompressing a full
    campaign's trials is most of the load time); None picks 2 for large archives on a multi-core machine.
    Raises `InvalidInput` when the file is missing, not HDF5, truncated or corrupt, not a protocol-runner
    archive (no root attribute `protocol_sha256`), lacks the `/configurations` group, or holds a dataset
    outside the layout's bounds or whose checksum does not match (archive/verify.py): every dataset is
    checked before the report uses anything.
    """
    archive = resolve_archive(Path(path))
    require_hdf5(archive)
    try:
        with h5py.File(archive, "r") as h5:
            names = check_root(h5, archive)
        # the file is closed before forking: HDF5 handles must not be shared across a fork
        configurations = _load_configurations(archive, names, workers)
        with h5py.File(archive, "r") as h5:
            Checker.of(h5, archive).check_tree(h5, skip=("configurations",))
            return _read(h5, archive, configurations)
    except InvalidInput:
        raise
    except (OSError, KeyError, ValueError, TypeError, RuntimeError) as exc:
        raise corrupt(archive, exc) from exc


def _load_chunk(archive: Path, names: list[str]) -> list[Configuration]:
    with h5py.File(archive, "r") as h5:
        checker = Checker.of(h5, archive)
        out = []
        for name in names:
            checker.check_tree(h5["configurations"][name])  # all of it, read or not: damage is named
            out.append(_read_configuration(name, h5["configurations"][name]))
        return out


def _load_configurations(archive: Path, names: list[str], workers: int | None) -> tuple[Configuration, ...]:
    if workers is None:
        workers = 2 if len(names) >= 12 and (os.cpu_count() or 1) >= 2 else 1
    configs: list[Configuration] | None = None
    if workers > 1 and len(names) >= 2:
        parts = map_in_processes(_load_one, [(archive, name) for name in names], workers, chunksize=2)
        configs = parts
    if configs is None:
        configs = _load_chunk(archive, names)
    return tuple(sorted(configs, key=lambda c: c.key))


def _load_one(item: tuple[Path, str]) -> Configuration:
    archive, name = item
    return _load_chunk(archive, [name])[0]


def decimate_for_plot(values: np.ndarray, max_points: int = MAX_PLOT_POINTS) -> np.ndarray:
    """Every k-th sample so that at most `max_points` remain (k = ceil(n / max_points)); read-only."""
    arr = np.asarray(values)
    if arr.size <= max_points:
        return _ro(arr)
    stride = math.ceil(arr.size / max_points)
    return _ro(arr[::stride])


# --------------------------------------------------------------------------------------------- internals


def _read(h5: h5py.File, archive: Path, configurations: tuple[Configuration, ...]) -> ReportData:
    session = _read_session(h5, archive)
    calibration = _read_calibration(h5)
    comparisons = _read_comparisons(h5)
    references = _read_references(h5)
    protocol_text = _scalar_str(h5["protocol"]) if "protocol" in h5 else ""
    notes: list[str] = []
    if not comparisons:
        notes.append(
            "The archive has no /comparisons groups: the report uses the thesis's comparisons (Chapter 5)."
        )
        comparisons = tuple(
            Comparison(name, parameter, section, title, keys, from_archive=False)
            for name, parameter, section, title, keys in THESIS_COMPARISONS
        )
    return ReportData(
        session=session,
        configurations=configurations,
        calibration=calibration,
        comparisons=comparisons,
        references=references,
        protocol_text=protocol_text,
        notes=tuple(notes),
    )


def _is_group(obj: Any) -> bool:
    return isinstance(obj, h5py.Group)


def _decode(value: Any) -> Any:
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    if isinstance(value, np.ndarray):
        if value.dtype.kind in ("S", "O"):
            return [_decode(v) for v in value.tolist()]
        return value
    if isinstance(value, np.generic):
        return value.item()
    return value


def _attr_str(attrs: h5py.AttributeManager, name: str, default: str = "") -> str:
    if name not in attrs:
        return default
    value = _decode(attrs[name])
    if isinstance(value, list):
        return ", ".join(str(v) for v in value)
    return str(value)


def _attr_float(attrs: h5py.AttributeManager, name: str, default: float = float("nan")) -> float:
    if name not in attrs:
        return default
    value = _decode(attrs[name])
    try:
        return float(np.asarray(value, dtype=float).reshape(-1)[0])
    except (TypeError, ValueError, IndexError):
        return default


def _attr_int(attrs: h5py.AttributeManager, name: str, default: int = 0) -> int:
    value = _attr_float(attrs, name, float("nan"))
    return default if math.isnan(value) else int(value)


def _attr_floats(attrs: h5py.AttributeManager, name: str) -> tuple[float, ...]:
    if name not in attrs:
        return ()
    value = _decode(attrs[name])
    try:
        return tuple(float(v) for v in np.asarray(value, dtype=float).reshape(-1))
    except (TypeError, ValueError):
        return ()


def _attr_bool(attrs: h5py.AttributeManager, name: str, default: bool = False) -> bool:
    if name not in attrs:
        return default
    value = _decode(attrs[name])
    if isinstance(value, str):
        return value.strip().lower() in ("true", "1", "yes")
    return bool(value)


def _scalar_str(ds: h5py.Dataset) -> str:
    value = _decode(ds[()])
    if isinstance(value, list):
        return "\n".join(str(v) for v in value)
    return str(value)


def _ro(arr: np.ndarray) -> np.ndarray:
    out = np.asarray(arr)
    if out.flags.writeable:
        out = out.view()
        out.flags.writeable = False
    return out


def _float_ds(group: h5py.Group, name: str) -> np.ndarray:
    if name not in group:
        return _ro(np.empty(0))
    return np.asarray(group[name][()], dtype=float).reshape(-1)


def _read_session(h5: h5py.File, archive: Path) -> SessionInfo:
    a = h5.attrs
    events: list[SessionEvent] = []
    checklists: list[ChecklistAnswer] = []
    if "session" in h5:
        sess = h5["session"]
        if "events" in sess:
            raw = _decode(sess["events"][()])
            lines = raw if isinstance(raw, list) else str(raw).splitlines()
            events.extend(_parse_event(str(line)) for line in lines if str(line).strip())
        if "checklists" in sess:
            for name, grp in sess["checklists"].items():
                if not _is_group(grp):
                    continue
                items_text = _attr_str(grp.attrs, "items", "[]")
                try:
                    items = tuple(str(x) for x in json.loads(items_text))
                except (json.JSONDecodeError, TypeError):
                    items = (items_text,)
                checklists.append(
                    ChecklistAnswer(
                        step_id=_attr_str(grp.attrs, "step_id", name.replace("__", ":")),
                        title=_attr_str(grp.attrs, "title"),
                        items=items,
                        answer=_attr_str(grp.attrs, "answer"),
                        answered_utc=_attr_str(grp.attrs, "answered_utc"),
                        automatic=_attr_bool(grp.attrs, "automatic"),
                    )
                )
    checklists.sort(key=lambda c: (c.answered_utc, c.step_id))
    only = tuple(int(v) for v in _attr_floats(a, "only"))
    return SessionInfo(
        archive_path=str(archive),
        protocol_name=_attr_str(a, "protocol_name", "(unnamed protocol)"),
        protocol_sha256=_attr_str(a, "protocol_sha256"),
        schema_version=_attr_int(a, "schema_version", 0),
        software_version=_attr_str(a, "software_version", "unknown"),
        mode=_attr_str(a, "mode", "unknown"),
        seed=_attr_int(a, "seed", 0),
        created_utc=_attr_str(a, "created_utc"),
        finished_utc=_attr_str(a, "finished_utc"),
        status=_attr_str(a, "status", "incomplete"),
        joint=_attr_str(a, "joint"),
        only=only,
        events=tuple(events),
        checklists=tuple(checklists),
    )


def _parse_event(line: str) -> SessionEvent:
    try:
        obj = json.loads(line)
    except json.JSONDecodeError:
        return SessionEvent(t_utc="", kind="unparsed", detail=line)
    if not isinstance(obj, dict):
        return SessionEvent(t_utc="", kind="unparsed", detail=line)
    detail = obj.get("detail", "")
    if not isinstance(detail, str):
        detail = json.dumps(detail, sort_keys=True)
    return SessionEvent(t_utc=str(obj.get("t_utc", "")), kind=str(obj.get("kind", "")), detail=detail)


def _read_calibration(h5: h5py.File) -> tuple[CalibrationCheck, ...]:
    if "calibration" not in h5:
        return ()
    checks: list[CalibrationCheck] = []
    for set_name, set_grp in h5["calibration"].items():
        if not _is_group(set_grp):
            continue
        for when, grp in set_grp.items():
            if not _is_group(grp):
                continue
            checks.append(
                CalibrationCheck(
                    set_name=set_name,
                    when=when,
                    step_id=_attr_str(grp.attrs, "step_id"),
                    verdict=_attr_str(grp.attrs, "verdict", "unknown"),
                    step_deg=_attr_float(grp.attrs, "step_deg"),
                    settle_error_deg=_attr_float(grp.attrs, "settle_error_deg"),
                    time_constant_s=_attr_float(grp.attrs, "time_constant_s"),
                    limits=_attr_str(grp.attrs, "limits"),
                    message=_attr_str(grp.attrs, "message"),
                    time_s=decimate_for_plot(_float_ds(grp, "time_s")),
                    angle_deg=decimate_for_plot(_float_ds(grp, "angle_deg")),
                    command_time_s=decimate_for_plot(_float_ds(grp, "command_time_s")),
                    command_deg=decimate_for_plot(_float_ds(grp, "command_deg")),
                )
            )
    order = {"before": 0, "after": 2}
    checks.sort(key=lambda c: (c.set_name, order.get(c.when, 1), c.when))
    return tuple(checks)


def _read_recording(grp: h5py.Group) -> Recording:
    return Recording(
        time_s=decimate_for_plot(_float_ds(grp, "time_s")),
        angle_deg=decimate_for_plot(_float_ds(grp, "angle_deg")),
        torque_nm=decimate_for_plot(_float_ds(grp, "torque_nm")),
        command_time_s=decimate_for_plot(_float_ds(grp, "command_time_s")),
        command_deg=decimate_for_plot(_float_ds(grp, "command_deg")),
        tick_lateness_p99_s=_attr_float(grp.attrs, "tick_lateness_p99_s"),
    )


def _trial_numbers(trials: h5py.Group) -> list[tuple[int, str]]:
    numbered: list[tuple[int, str]] = []
    for name in trials:
        try:
            numbered.append((int(name), name))
        except ValueError:
            continue
    return sorted(numbered)


def _read_configuration(name: str, grp: h5py.Group) -> Configuration:
    a = grp.attrs
    settings: dict[str, object] = {}
    for attr_name in sorted(a.keys()):
        if attr_name in _IDENTITY_ATTRS:
            continue
        value = _decode(a[attr_name])
        if isinstance(value, np.ndarray):
            value = tuple(value.tolist())
        elif isinstance(value, list):
            value = tuple(value)
        settings[attr_name] = value
    trials: list[Trial] = []
    angles: list[np.ndarray] = []
    torques: list[np.ndarray] = []
    raw_loaded = False
    if "trials" in grp:
        for number, tname in _trial_numbers(grp["trials"]):
            tgrp = grp["trials"][tname]
            on = off = None
            has_raw = "brace_on" in tgrp or "brace_off" in tgrp
            # Only the first recorded trial's raw data is plotted (angle/torque vs time): reading and
            # decompressing the others would dominate the report's regeneration time.
            if has_raw and not raw_loaded:
                on = _read_recording(tgrp["brace_on"]) if "brace_on" in tgrp else None
                off = _read_recording(tgrp["brace_off"]) if "brace_off" in tgrp else None
                raw_loaded = True
            processed = None
            if "processed" in tgrp:
                pgrp = tgrp["processed"]
                angle = _float_ds(pgrp, "angle_deg")
                torque = _float_ds(pgrp, "brace_torque_nm")
                n = min(angle.size, torque.size)
                angle, torque = angle[:n], torque[:n]
                angles.append(angle)
                torques.append(torque)
                processed = ProcessedTrial(
                    angle_deg=decimate_for_plot(angle),
                    brace_torque_nm=decimate_for_plot(torque),
                    subtraction=_attr_str(pgrp.attrs, "subtraction", "equal_angle"),
                )
            trials.append(
                Trial(number=number, brace_on=on, brace_off=off, processed=processed, recorded=has_raw)
            )
    angle_min, angle_max, slope = _summary(angles, torques)
    energy = _float_ds(grp, "energy_loss_j")
    cycle_trial = _float_ds(grp, "energy_cycle_trial")
    if cycle_trial.size != energy.size:
        cycle_trial = np.zeros(energy.size)
    return Configuration(
        name=name,
        key=_attr_int(a, "key", _key_from_name(name)),
        run=_attr_int(a, "run", 0),
        set_name=_attr_str(a, "set"),
        condition=_attr_str(a, "condition"),
        profile=_attr_str(a, "profile"),
        status=_attr_str(a, "status", "complete" if trials else "not run"),
        n_trials_planned=_attr_int(a, "n_trials", len(trials)),
        settings=settings,
        trials=tuple(trials),
        energy_loss_j=_ro(energy),
        energy_cycle_trial=_ro(cycle_trial),
        bouc_wen=_read_bouc_wen(grp["fits/bouc_wen"]) if "fits/bouc_wen" in grp else None,
        spring=_read_spring(grp["fits/spring"]) if "fits/spring" in grp else None,
        angle_min_deg=angle_min,
        angle_max_deg=angle_max,
        torque_slope_nm_per_deg=slope,
    )


def _key_from_name(name: str) -> int:
    digits = "".join(ch for ch in name if ch.isdigit())
    return int(digits) if digits else 0


def _summary(angles: list[np.ndarray], torques: list[np.ndarray]) -> tuple[float, float, float]:
    """Angle range reached and least-squares torque-angle slope (N*m/deg) over all processed samples."""
    # accumulate the sums of the normal equations trial by trial (no concatenated copy)
    n = sx = sy = sxx = sxy = 0.0
    lo, hi = math.inf, -math.inf
    for angle, torque in zip(angles, torques, strict=True):
        ok = np.isfinite(angle) & np.isfinite(torque)
        if not ok.all():
            angle, torque = angle[ok], torque[ok]
        if angle.size == 0:
            continue
        n += angle.size
        sx += float(angle.sum())
        sy += float(torque.sum())
        sxx += float(np.einsum("i,i->", angle, angle))
        sxy += float(np.einsum("i,i->", angle, torque))
        lo, hi = min(lo, float(angle.min())), max(hi, float(angle.max()))
    if n < 2:
        return float("nan"), float("nan"), float("nan")
    denom = sxx - sx * sx / n
    slope = (sxy - sx * sy / n) / denom if denom > 1e-12 * max(sxx, 1.0) else float("nan")
    return lo, hi, slope


def _read_bouc_wen(grp: h5py.Group) -> BoucWenFit:
    a = grp.attrs
    return BoucWenFit(
        A=_attr_float(a, "A"),
        n=_attr_float(a, "n"),
        beta=_attr_floats(a, "beta"),
        rmse_nm=_attr_float(a, "rmse_nm"),
        r2=_attr_float(a, "r2"),
        A_std=_attr_float(a, "A_std"),
        n_std=_attr_float(a, "n_std"),
        beta_std=_attr_floats(a, "beta_std"),
        cv_rmse_nm=_attr_floats(a, "cv_rmse_nm"),
        n_starts=_attr_int(a, "n_starts", 0),
        angle_deg=decimate_for_plot(_float_ds(grp, "angle_deg")),
        torque_nm=decimate_for_plot(_float_ds(grp, "torque_nm")),
        model_torque_nm=decimate_for_plot(_float_ds(grp, "model_torque_nm")),
    )


def _read_spring(grp: h5py.Group) -> SpringFit:
    a = grp.attrs
    return SpringFit(
        applicable=_attr_bool(a, "applicable", True),
        max_preload_mm=_attr_float(a, "max_preload_mm"),
        zero_offset_deg=_attr_float(a, "zero_offset_deg"),
        rmse_nm=_attr_float(a, "rmse_nm"),
        angle_deg=decimate_for_plot(_float_ds(grp, "angle_deg")),
        model_torque_nm=decimate_for_plot(_float_ds(grp, "model_torque_nm")),
    )


def _read_comparisons(h5: h5py.File) -> tuple[Comparison, ...]:
    if "comparisons" not in h5:
        return ()
    out: list[Comparison] = []
    for name, grp in h5["comparisons"].items():
        if not _is_group(grp):
            continue
        keys = tuple(int(k) for k in _attr_floats(grp.attrs, "configurations"))
        out.append(
            Comparison(
                name=name,
                parameter=_attr_str(grp.attrs, "parameter", name),
                section=_attr_str(grp.attrs, "section"),
                title=_attr_str(grp.attrs, "title", name),
                configurations=keys,
                from_archive=True,
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


def _read_references(h5: h5py.File) -> tuple[ReferenceDataset, ...]:
    if "reference" not in h5:
        return ()
    out: list[ReferenceDataset] = []
    for name, grp in h5["reference"].items():
        if not _is_group(grp) or "angle_deg" not in grp or "torque_nm" not in grp:
            continue
        angle = _float_ds(grp, "angle_deg")
        torque = _float_ds(grp, "torque_nm")
        n = min(angle.size, torque.size)
        out.append(
            ReferenceDataset(
                source=_attr_str(grp.attrs, "source", f"/reference/{name}"),
                title=_attr_str(grp.attrs, "title", name),
                angle_deg=decimate_for_plot(angle[:n], 4 * MAX_PLOT_POINTS),
                torque_nm=decimate_for_plot(torque[:n], 4 * MAX_PLOT_POINTS),
            )
        )
    return tuple(out)
