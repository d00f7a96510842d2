"""`run-protocol --report ARCHIVE --export-mat DIR`: the archive as MATLAB 5 `.mat` files, one per
configuration (`config_NN.mat`) and one for the session (`session.mat`); their variables are listed in
docs/matlab.md, the naming and type rules are archive/matlab.py's.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from scipy.io import savemat

from .. import __version__
from ..errors import InvalidInput, make_output_dir
from .attrs import ATTRIBUTE_DIGESTS
from .diskfull import DiskFull, is_disk_full
from .matlab import (
    Units,
    attrs_struct,
    dataset_value,
    group_struct,
    matlab_value,
    put_field,
    text,
)
from .outputs import create_binary, refuse_special, temporary_beside
from .paths import CALIBRATION, CHECKLISTS, COMPARISONS, CONFIGURATIONS, JOINTS, joint_groups
from .verify import validate_archive  # clear messages for foreign or damaged files

SESSION_FILE = "session"


def export_mat(archive: Path, out_dir: Path) -> list[Path]:
    archive = validate_archive(archive)
    make_output_dir(out_dir, "--export-mat")
    where = str(archive)
    written: list[Path] = []
    try:
        with h5py.File(archive, "r") as f:
            configs = f["configurations"]
            names = [n for n in configs if isinstance(configs[n], h5py.Group)]
            if not names:
                raise InvalidInput(f"{archive}: no configurations to export")
            meta = attrs_struct(f, where)
            meta.setdefault("operator", _operator(f))
            meta["archive"] = archive.name
            meta["exported_by"] = f"protocol-runner {__version__}"
            files: dict[str, str] = {SESSION_FILE: SESSION_FILE}
            summary: dict[str, Any] = {}
            for name in names:
                stem = put_field(files, name, name, prefix="config")
                content = _configuration(f, configs[name], meta, where)
                written.append(_save(out_dir / f"{stem}.mat", content))
                put_field(summary, name, _summary(f, configs[name], f"{stem}.mat", where), prefix="config")
            written.append(_save(out_dir / f"{SESSION_FILE}.mat", _session(f, meta, summary, where)))
    except InvalidInput:
        raise
    except (OSError, KeyError, ValueError, TypeError, RuntimeError) as exc:
        raise InvalidInput(f"{archive}: cannot export ({exc}); the archive may be damaged") from None
    return written


def _operator(f: h5py.File) -> str:
    """Who answered the operator checklists, as far as the archive says (it records no person's name)."""
    checklists = f.get(CHECKLISTS)
    if not isinstance(checklists, h5py.Group):
        return ""
    automatic = [
        bool(g.attrs.get("automatic", False)) for g in checklists.values() if isinstance(g, h5py.Group)
    ]
    if not automatic:
        return ""
    if all(automatic):
        return "automatic (--dry-run or --yes)"
    return "console" if not any(automatic) else "console and automatic"


def _trial_order(name: str) -> tuple[int, int, str]:
    return (0, int(name), "") if name.isdigit() else (1, 0, name)


def _configuration(f: h5py.File, cfg: h5py.Group, meta: dict[str, Any], where: str) -> dict[str, Any]:
    """A configuration's variables: of a single joint at the top level (`trial_1`, `energy_loss_j`,
    `bouc_wen`, `calibration`, ...) whatever the archive's layout (the joint's part of each group merged
    into the group's struct); of several joints, each joint's under `joints.<joint>` and what they share
    at the top."""
    units = Units(where)
    content: dict[str, Any] = {"meta": meta, "configuration": attrs_struct(cfg, where)}
    archive_joints = text(f.attrs.get("joint", ""))
    parts = joint_groups(cfg, archive_joints)
    records = _records(f, cfg)
    trials = cfg.get("trials") if isinstance(cfg.get("trials"), h5py.Group) else None
    if len(parts) == 1:
        joint, part = parts[0]
        content.update(_joint(joint, part, trials, archive_joints, units, where, shared=True))
        if records is not None:
            content["calibration"] = _calibration(records, joint, archive_joints, units, where, shared=True)
    else:
        joints: dict[str, Any] = {}
        for joint, part in parts:
            struct = _joint(joint, part, trials, archive_joints, units, where)
            if records is not None:
                struct["calibration"] = _calibration(records, joint, archive_joints, units, where)
            put_field(joints, joint, struct)
        content["joints"] = joints
        for n, trial in sorted((trials or {}).items(), key=lambda item: _trial_order(item[0])):
            if isinstance(trial, h5py.Group):
                put_field(content, n, _shared(trial, units, where), prefix="trial")
        for name, obj in cfg.items():
            if isinstance(obj, h5py.Dataset):  # the total energy of all joints together
                units.add(put_field(content, name, dataset_value(obj, where)), obj)
        _energy_stats(cfg, "total_energy_loss_j", content, "total_energy", units, where)
        if records is not None:
            content["calibration"] = _shared(records, units, where)
    content["units"] = units.struct()
    return content


def _records(f: h5py.File, cfg: h5py.Group) -> h5py.Group | None:
    """The calibration records of the configuration's set (`/calibration/<set>`), or None."""
    calibration = f.get("calibration")
    cal_set = cfg.attrs.get("set")
    if not isinstance(calibration, h5py.Group) or cal_set is None:
        return None
    records = calibration.get(text(cal_set))
    return records if isinstance(records, h5py.Group) else None


def _calibration(
    records: h5py.Group, joint: str, archive_joints: str, units: Units, where: str, *, shared: bool = False
) -> dict[str, Any]:
    """`joint`'s calibration records (`before`, `after`, `resume_n`) as a struct of structs."""
    out: dict[str, Any] = {}
    for when, record in records.items():
        if isinstance(record, h5py.Group):
            put_field(out, when, _part_struct(record, joint, archive_joints, units, where, shared))
    return out


def _joint(
    joint: str,
    part: h5py.Group,
    trials: h5py.Group | None,
    archive_joints: str,
    units: Units,
    where: str,
    *,
    shared: bool = False,
) -> dict[str, Any]:
    """One joint's variables: `trial_n` (its processed data and its recordings), its energies and fits.
    `part` is the joint's part of the configuration group; `shared` merges what the joint's recordings share
    with other joints' (a single joint's export: its recordings whole, whatever the layout)."""
    out: dict[str, Any] = {}
    own_trials = part.get("trials")
    names = set(trials or ()) | set(own_trials if isinstance(own_trials, h5py.Group) else ())
    for n in sorted(names, key=_trial_order):
        trial: dict[str, Any] = {}
        processed = part.get(f"trials/{n}/processed")
        if isinstance(processed, h5py.Group):
            trial.update(group_struct(processed, units, where))
        group = trials.get(n) if trials is not None else None
        for side, obj in group.items() if isinstance(group, h5py.Group) else ():
            if side != "processed" and isinstance(obj, h5py.Group):
                put_field(trial, side, _part_struct(obj, joint, archive_joints, units, where, shared))
        put_field(out, n, trial, prefix="trial")
    for name, obj in part.items():
        if name in ("trials", JOINTS):
            continue
        if name == "fits" and isinstance(obj, h5py.Group):
            for fit, group in obj.items():
                if isinstance(group, h5py.Group):
                    put_field(out, fit, group_struct(group, units, where))
        elif isinstance(obj, h5py.Group):
            put_field(out, name, group_struct(obj, units, where))
        elif isinstance(obj, h5py.Dataset):
            units.add(put_field(out, name, dataset_value(obj, where)), obj)
    _energy_stats(part, "energy_loss_j", out, "energy", units, where)
    return out


def _part_struct(
    group: h5py.Group, joint: str, archive_joints: str, units: Units, where: str, shared: bool
) -> dict[str, Any]:
    """`joint`'s part of a group keyed by joint (a recording, a calibration record) as a struct; `shared`
    adds what the group holds for every joint (its attributes, common time base and scaling)."""
    own = dict(joint_groups(group, archive_joints)).get(joint)
    out = group_struct(group, units, where, skip=(JOINTS,)) if shared or own is None else {}
    if own is not None and own is not group:
        out.update(group_struct(own, units, where))
    return out


def _shared(group: h5py.Group, units: Units, where: str) -> dict[str, Any]:
    """What a group of several joints (a trial, a set's calibration records) holds for all of them: each
    subgroup's attributes and members outside `joints/` (a recording's common time base, its scaling; a
    calibration record's verdict and message)."""
    out: dict[str, Any] = {}
    for name, obj in group.items():
        if isinstance(obj, h5py.Group):
            put_field(out, name, group_struct(obj, units, where, skip=(JOINTS,)))
    return out


def _energy_stats(
    group: h5py.Group, dataset: str, content: dict[str, Any], prefix: str, units: Units, where: str
) -> None:
    """`<prefix>_mean_j` and `<prefix>_std_j` of the energy per cycle `dataset` (the attributes the archive
    stores with it, else the mean and sample standard deviation of its values)."""
    loss = group.get(dataset)
    if not isinstance(loss, h5py.Dataset):
        return
    for stat, value in _stats(loss, where).items():
        content[f"{prefix}_{stat}"] = value
        units.add(f"{prefix}_{stat}", loss)


def _stats(loss: h5py.Dataset, where: str) -> dict[str, Any]:
    if "mean_j" in loss.attrs or "std_j" in loss.attrs:
        return {
            stat: matlab_value(loss.attrs[stat], f"{where}: {loss.name}@{stat}")
            for stat in ("mean_j", "std_j")
            if stat in loss.attrs
        }
    values = np.asarray(loss[()], dtype=np.float64).reshape(-1)
    return {
        "mean_j": float(values.mean()) if values.size else math.nan,
        "std_j": float(values.std(ddof=1)) if values.size > 1 else math.nan,
    }


def _summary(f: h5py.File, cfg: h5py.Group, file: str, where: str) -> dict[str, Any]:
    """A configuration's line of `session.mat`: its attributes, `file`, and its energy per cycle (of a
    single joint at the top; of several, per joint in `joints.<joint>` and `total_energy_*` at the top)."""
    out = attrs_struct(cfg, where)
    parts = joint_groups(cfg, text(f.attrs.get("joint", "")))
    if len(parts) == 1:
        out.update(_energy_summary(parts[0][1], "energy_loss_j", "energy", where))
    else:
        joints: dict[str, Any] = {}
        for joint, part in parts:
            put_field(joints, joint, _energy_summary(part, "energy_loss_j", "energy", where))
        out["joints"] = joints
        out.update(_energy_summary(cfg, "total_energy_loss_j", "total_energy", where))
    out["file"] = file
    return out


def _energy_summary(group: h5py.Group, dataset: str, prefix: str, where: str) -> dict[str, Any]:
    loss = group.get(dataset)
    if not isinstance(loss, h5py.Dataset):
        return {}
    out = {f"{prefix}_{stat}": value for stat, value in _stats(loss, where).items()}
    out[f"{prefix}_cycles"] = float(loss.shape[0]) if loss.ndim == 1 else 0.0
    return out


def _session(f: h5py.File, meta: dict[str, Any], summary: dict[str, Any], where: str) -> dict[str, Any]:
    units = Units(where)
    content: dict[str, Any] = {"meta": meta}
    archive_joints = text(f.attrs.get("joint", ""))
    for name, obj in f.items():
        if name == CONFIGURATIONS:
            continue
        if name in (CALIBRATION, COMPARISONS) and isinstance(obj, h5py.Group):
            put_field(content, name, _keyed_groups(obj, archive_joints, units, where))
        elif isinstance(obj, h5py.Group):
            put_field(content, name, group_struct(obj, units, where))
        elif isinstance(obj, h5py.Dataset):
            field = put_field(content, name, dataset_value(obj, where))
            units.add(field, obj)
            for key in obj.attrs:
                if key not in ("units", ATTRIBUTE_DIGESTS):
                    put_field(
                        content, f"{field}_{key}", matlab_value(obj.attrs[key], f"{where}: {obj.name}@{key}")
                    )
    content["configurations"] = summary
    content["units"] = units.struct()
    return content


def _keyed_groups(group: h5py.Group, archive_joints: str, units: Units, where: str) -> dict[str, Any]:
    """`/calibration` (its records `<set>/<when>`) or `/comparisons` (`<name>`) for `session.mat`: keyed by
    joint (`joints.<joint>`) when it holds several joints, else that joint's part merged into it, as in
    `config_NN.mat`."""
    out = attrs_struct(group, where)
    for name, obj in group.items():
        if not isinstance(obj, h5py.Group):
            continue
        if group.name == f"/{CALIBRATION}":  # a set: its records
            put_field(out, name, _keyed_groups(obj, archive_joints, units, where))
            continue
        parts = joint_groups(obj, archive_joints)
        if len(parts) == 1:
            put_field(out, name, _part_struct(obj, parts[0][0], archive_joints, units, where, shared=True))
        else:
            put_field(out, name, group_struct(obj, units, where))
    return out


def _save(path: Path, content: dict[str, Any]) -> Path:
    """Write `content` to `path` atomically (a half-written file never has the final name); a `path` that is
    not a regular file (a link, a device, a FIFO) is refused (archive/outputs.py)."""
    refuse_special(path, "--export-mat")
    partial = temporary_beside(path)
    try:
        with create_binary(partial) as fh:
            savemat(fh, content, do_compression=True, oned_as="column", long_field_names=True)
        os.replace(partial, path)
    except BaseException as exc:
        partial.unlink(missing_ok=True)
        if not isinstance(exc, OSError):
            raise
        if is_disk_full(exc):  # as everywhere: one message, exit 130; the files written before are complete
            raise DiskFull(
                f"disk full while writing {path} (--export-mat): the .mat files written before it are complete; "
                "free some space and run the export again"
            ) from None
        raise InvalidInput(f"--export-mat: cannot write {path}: {exc.strerror or exc}") from None
    return path
