"""`run-protocol --report ARCHIVE --export-mat DIR`: the archive as MATLAB 5 `.mat` files (docs/matlab.md).

One file per configuration, `config_NN.mat`, and one for the session, `session.mat` (scipy.io.savemat,
compressed; MATLAB's and Octave's `load` read them). Types, names and orientation: archive/matlab.py.

`config_NN.mat`:

    meta            struct: the archive's root attributes (protocol_name, protocol_sha256, software_version,
                    schema_version, seed, mode, status, joint, only, created_utc, finished_utc), operator,
                    archive (file name), exported_by
    units           struct: the unit of every array in the file, by field name (units.angle_deg = 'deg')
    configuration   struct of the configuration's attributes (key, run, set, status, factors, each declared
                    factor's level label, each factor quantity `<factor>.<quantity>` as `<factor>__<quantity>`,
                    settings_json, device_json, trajectory_name)
    trial_n         struct per trial n: the processed data (time_s, angle_deg, brace_torque_nm) with the
                    processed group's attributes, and the raw recordings as structs brace_on and brace_off
                    (time_s, angle_deg, torque_nm, *_codes, command_*, tick_lateness_s, attributes;
                    brace_off.scaling: the brace-off scaling iterations)
    energy_loss_j   energy lost per complete cycle (J); energy_cycle_trial: each cycle's trial number;
                    energy_mean_j, energy_std_j
    bouc_wen        struct: parameters (A, n, beta, rmse_nm, r2, ...) and fitted curves (angle_deg,
                    torque_nm, model_torque_nm, segment_lengths), when fitted
    elements        struct: the element fit (fitted `<element>.<param>` as `<element>__<param>`, rmse_nm, ...)
                    and curves (angle_deg, torque_nm, model_torque_nm), when fitted
    calibration     struct: the calibration records of the configuration's set (before, after, resume_n)

`session.mat`: meta, units, and every root member of the archive but the configurations: protocol (text)
and protocol_filename, rig (text) and rig_filename, plan (JSON text), session (events: cell of JSON lines; checklists), calibration
(every set), comparisons, reference; and configurations: a summary struct per configuration (its
attributes, energy_mean_j, energy_std_j, energy_cycles and the name of its file).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import h5py
from scipy.io import savemat

from .. import __version__
from ..errors import InvalidInput, make_output_dir
from .attrs import ATTRIBUTE_DIGESTS
from .diskfull import DiskFull, is_disk_full
from .matlab import Units, attrs_struct, dataset_value, group_struct, matlab_value, put_field, text
from .outputs import create_binary, refuse_special, temporary_beside
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
            meta = _meta(f, archive)
            files: dict[str, str] = {SESSION_FILE: SESSION_FILE}
            summary: dict[str, Any] = {}
            for name in names:
                stem = put_field(files, name, name, prefix="config")
                content = _configuration(f, configs[name], meta, where)
                written.append(_save(out_dir / f"{stem}.mat", content))
                put_field(summary, name, _summary(configs[name], f"{stem}.mat", where), prefix="config")
            written.append(_save(out_dir / f"{SESSION_FILE}.mat", _session(f, meta, summary, where)))
    except InvalidInput:
        raise
    except (OSError, KeyError, ValueError, TypeError, RuntimeError) as exc:
        raise InvalidInput(f"{archive}: cannot export ({exc}); the archive may be damaged") from None
    return written


def _meta(f: h5py.File, archive: Path) -> dict[str, Any]:
    meta = attrs_struct(f, str(archive))
    meta.setdefault("operator", _operator(f))
    meta["archive"] = archive.name
    meta["exported_by"] = f"protocol-runner {__version__}"
    return meta


def _operator(f: h5py.File) -> str:
    """Who answered the operator checklists, as far as the archive says (it records no person's name)."""
    checklists = f.get("session/checklists")
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
    units = Units(where)
    content: dict[str, Any] = {"meta": meta, "configuration": attrs_struct(cfg, where)}
    for name, obj in cfg.items():
        if name == "trials" and isinstance(obj, h5py.Group):
            for n in sorted(obj, key=_trial_order):
                if isinstance(obj[n], h5py.Group):
                    put_field(content, n, _trial(obj[n], units, where), prefix="trial")
        elif name == "fits" and isinstance(obj, h5py.Group):
            for fit, group in obj.items():
                if isinstance(group, h5py.Group):
                    put_field(content, fit, group_struct(group, units, where))
        elif isinstance(obj, h5py.Group):
            put_field(content, name, group_struct(obj, units, where))
        elif isinstance(obj, h5py.Dataset):
            units.add(put_field(content, name, dataset_value(obj, where)), obj)
    _energy_stats(cfg, content, units, where)
    calibration = f.get("calibration")
    cal_set = cfg.attrs.get("set")
    if isinstance(calibration, h5py.Group) and cal_set is not None:
        records = calibration.get(text(cal_set))
        if isinstance(records, h5py.Group):
            put_field(content, "calibration", group_struct(records, units, where))
    content["units"] = units.struct()
    return content


def _trial(group: h5py.Group, units: Units, where: str) -> dict[str, Any]:
    """A trial: its processed data and their attributes as its own fields, raw recordings as structs."""
    trial: dict[str, Any] = {}
    processed = group.get("processed")
    if isinstance(processed, h5py.Group):
        trial.update(group_struct(processed, units, where))
    for sub, obj in group.items():
        if sub != "processed" and isinstance(obj, h5py.Group):
            put_field(trial, sub, group_struct(obj, units, where))
    return trial


def _energy_stats(cfg: h5py.Group, content: dict[str, Any], units: Units, where: str) -> None:
    loss = cfg.get("energy_loss_j")
    if isinstance(loss, h5py.Dataset):
        for stat in ("mean_j", "std_j"):
            if stat in loss.attrs:
                content[f"energy_{stat}"] = matlab_value(loss.attrs[stat], f"{where}: {loss.name}@{stat}")
                units.add(f"energy_{stat}", loss)


def _summary(cfg: h5py.Group, file: str, where: str) -> dict[str, Any]:
    out = attrs_struct(cfg, where)
    loss = cfg.get("energy_loss_j")
    if isinstance(loss, h5py.Dataset):
        out["energy_cycles"] = float(loss.shape[0]) if loss.ndim == 1 else 0.0
        for stat in ("mean_j", "std_j"):
            if stat in loss.attrs:
                out[f"energy_{stat}"] = matlab_value(loss.attrs[stat], f"{where}: {loss.name}@{stat}")
    out["file"] = file
    return out


def _session(f: h5py.File, meta: dict[str, Any], summary: dict[str, Any], where: str) -> dict[str, Any]:
    units = Units(where)
    content: dict[str, Any] = {"meta": meta}
    for name, obj in f.items():
        if name == "configurations":
            continue
        if isinstance(obj, h5py.Group):
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
