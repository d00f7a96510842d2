"""Tidy CSV tables of an archive (`--export`, docs/report.md "Tidy exports"): cycles, trials and
configurations (the report summary's statistics, `report.headline`), and the model tables `models.csv`,
`elements.csv` and `predictions.csv`; units in the names, every driven joint's rows from its own data.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import h5py
import numpy as np

from protocol_runner.analysis.cycles import complete_cycles
from protocol_runner.analysis.validation import AnalysisError
from protocol_runner.archive.diskfull import DiskFull, is_disk_full
from protocol_runner.archive.model_results import MODEL_VALUES, read_element_model, read_models
from protocol_runner.archive.outputs import create_new, refuse_special, temporary_beside
from protocol_runner.archive.paths import joint_groups
from protocol_runner.errors import InvalidInput
from protocol_runner.report.h5read import attr_str
from protocol_runner.report.headline import configuration_stats
from protocol_runner.report.load import load_report_data
from protocol_runner.report.model import BraceOffMatch, Configuration, ReportData
from protocol_runner.report.predictions import AngleRanges, prediction_row, predictions

if TYPE_CHECKING:
    from protocol_runner.protocol.only import KeySelection

CYCLE_COLUMNS = (
    "configuration",
    "set",
    "trial",
    "brace",
    "joint",
    "cycle",
    "energy_j",
    "angle_min_deg",
    "angle_max_deg",
    "torque_peak_nm",
)
TRIAL_COLUMNS = (
    "configuration",
    "set",
    "joint",
    "trial",
    "cycles",
    "energy_mean_j",
    "energy_sd_j",
    "angle_min_deg",
    "angle_max_deg",
    "torque_peak_nm",
    "brace_off_scaling_error_deg",
    "brace_off_scaling_runs",
    "brace_off_scaling_converged",
    "clipped_fraction",
)
STAT_COLUMNS = (
    "trials",
    "cycles",
    "energy_mean_j",
    "energy_ci95_low_j",
    "energy_ci95_high_j",
    "energy_cv_between_trials",
    "angle_min_deg",
    "angle_max_deg",
    "bouc_wen_rmse_nm",
    "bouc_wen_r2",
)

MODEL_COLUMNS = ("configuration", "joint", "model", *MODEL_VALUES)
ELEMENT_COLUMNS = (
    "configuration",
    "joint",
    "element",
    "parameter",
    "value",
    "ci95_low",
    "ci95_high",
    "identified",
    "note",
)
PREDICTION_COLUMNS = (
    "from_configuration",
    "to_configuration",
    "joint",
    "model",
    "rmse_nm",
    "energy_predicted_j",
    "energy_predicted_ci95_low_j",
    "energy_predicted_ci95_high_j",
    "energy_measured_j",
    "source_range_low_deg",
    "source_range_high_deg",
    "target_range_low_deg",
    "target_range_high_deg",
    "beyond_source_deg",
    "extrapolated",
)


FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")
"""How a spreadsheet recognises a formula (or a cell that pastes as one) at the start of a cell."""


def _cell(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return "" if not math.isfinite(value) else repr(value)
    if isinstance(value, tuple | list):
        return ";".join(_cell(v) for v in value)
    if isinstance(value, int | np.integer | np.floating):
        return str(value)
    return text_cell(str(value))


def text_cell(text: str) -> str:
    """A text cell as a spreadsheet shows it, never runs it: one starting like a formula gets a leading
    single quote (OWASP, against CSV injection); text that is a number (`-1.5`) is kept as it is."""
    if not text.startswith(FORMULA_STARTS):
        return text
    try:
        float(text)
    except ValueError:
        return "'" + text
    return text


def _write(path: Path, columns: Sequence[str], rows: Iterable[Sequence[object]]) -> Path:
    """Write one table through a temporary file and a rename; on any failure (a full disk, an interruption)
    the temporary file is removed and `path` is left as it was."""
    refuse_special(path, "--export")
    tmp = temporary_beside(path)
    try:
        with create_new(tmp, newline="") as fh:
            writer = csv.writer(fh, lineterminator="\n")
            writer.writerow([text_cell(c) for c in columns])
            for row in rows:
                writer.writerow([_cell(v) for v in row])
        os.replace(tmp, path)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError) and is_disk_full(exc):
            raise DiskFull(
                f"disk full while writing {path} (--export): the tables written before it are complete; "
                "free some space and run the export again"
            ) from None
        raise
    return path


def _processed(
    h5: h5py.File, cfg: Configuration, trial: int, archive_joints: str
) -> tuple[np.ndarray, np.ndarray] | None:
    """The processed angle and brace torque of `cfg`'s joint in trial `trial`, or None."""
    group = h5.get(f"configurations/{cfg.name}")
    if not isinstance(group, h5py.Group):
        return None
    own = dict(joint_groups(group, archive_joints)).get(cfg.joint)
    path = f"trials/{trial}/processed"
    if own is None or path not in own:
        return None
    grp = own[path]
    if "angle_deg" not in grp or "brace_torque_nm" not in grp:
        return None
    angle = np.asarray(grp["angle_deg"][()], dtype=float)
    torque = np.asarray(grp["brace_torque_nm"][()], dtype=float)
    n = min(angle.size, torque.size)
    return angle[:n], torque[:n]


def _cycle_geometry(
    signal: tuple[np.ndarray, np.ndarray] | None, n_cycles: int
) -> list[tuple[float, float, float]]:
    blank: list[tuple[float, float, float]] = [(math.nan, math.nan, math.nan)] * n_cycles
    if signal is None or n_cycles == 0:
        return blank
    angle, torque = signal
    try:
        spans = complete_cycles(angle)
    except (AnalysisError, ValueError):  # an odd trial leaves the columns empty; the energies stay
        return blank
    if len(spans) != n_cycles:
        return blank
    out: list[tuple[float, float, float]] = []
    for start, stop in spans:
        a, t = angle[start : stop + 1], torque[start : stop + 1]
        out.append((float(np.nanmin(a)), float(np.nanmax(a)), float(np.nanmax(np.abs(t)))))
    return out


def _rows(h5: h5py.File, data: ReportData) -> tuple[list[list[object]], list[list[object]]]:
    cycles: list[list[object]] = []
    trials: list[list[object]] = []
    for cfg in data.configurations:
        energy = np.asarray(cfg.energy_loss_j, dtype=float)
        ids = np.asarray(cfg.energy_cycle_trial)
        numbers = sorted({t.number for t in cfg.trials} | {int(i) for i in ids})
        matches = {t.number: t.match for t in cfg.trials}  # read by load.brace_off_match
        for number in numbers:
            own = energy[ids == number] if ids.size == energy.size else np.empty(0)
            signal = _processed(h5, cfg, number, data.session.joint)
            geometry = _cycle_geometry(signal, own.size)
            for i, (e, geo) in enumerate(zip(own, geometry, strict=True), start=1):
                cycles.append([cfg.key, cfg.set_name, number, "on-off", cfg.joint, i, float(e), *geo])
            lo = hi = peak = math.nan
            if signal is not None and signal[0].size:
                lo, hi = float(np.nanmin(signal[0])), float(np.nanmax(signal[0]))
                peak = float(np.nanmax(np.abs(signal[1])))
            mean = float(own.mean()) if own.size else math.nan
            sd = float(own.std(ddof=1)) if own.size > 1 else math.nan
            m = matches.get(number, BraceOffMatch())
            match = [m.scaling_error_deg, m.scaling_runs, m.scaling_converged, m.clipped_fraction]
            trials.append(
                [cfg.key, cfg.set_name, cfg.joint, number, int(own.size), mean, sd, lo, hi, peak, *match]
            )
    return cycles, trials


def _configuration_rows(data: ReportData) -> tuple[list[str], list[list[object]]]:
    # per declared factor its level label, then its quantities `<factor>.<quantity>`: first seen first
    setting_names: list[str] = []
    for cfg in data.configurations:
        setting_names.extend(k for k in cfg.settings.flat() if k not in setting_names)
    columns = ["configuration", "set", "joint", "profile", "trajectory", *setting_names, *STAT_COLUMNS]
    rows: list[list[object]] = []
    for cfg in data.configurations:
        s = configuration_stats(cfg)
        flat = cfg.settings.flat()
        rows.append(
            [
                cfg.key,
                cfg.set_name,
                cfg.joint,
                cfg.profile,
                cfg.settings.trajectory,
                *(flat.get(name) for name in setting_names),
                s.trials,
                s.cycles,
                s.energy.mean,
                s.energy.low,
                s.energy.high,
                s.energy.cv,
                s.angle_min_deg,
                s.angle_max_deg,
                s.fit_rmse_nm,
                s.fit_r2,
            ]
        )
    return columns, rows


Table = tuple[str, Sequence[str], list[list[object]]]


def _ranges(r: AngleRanges | None) -> list[object]:
    """A model's angle range columns of predictions.csv (empty when it has none)."""
    if r is None:
        return [math.nan] * 5 + [None]
    return [*r.source_deg, *r.target_deg, r.beyond_source_deg, r.extrapolated]


def _model_tables(archive: Path, protocol_text: str) -> tuple[Table, ...]:
    """The rows of models.csv, elements.csv and predictions.csv of `archive`, each as (file name, columns,
    rows); a number that does not exist is NaN."""
    models: list[list[object]] = []
    elements: list[list[object]] = []
    with h5py.File(archive, "r") as h5:
        archive_joints = attr_str(h5.attrs, "joint")
        configs = h5.get("configurations")
        for name in sorted(configs) if isinstance(configs, h5py.Group) else ():
            key = int(configs[name].attrs.get("key", int(name.rsplit("_", 1)[-1])))
            for joint, owner in joint_groups(configs[name], archive_joints):
                if "fits/models" in owner:
                    models += ([key, joint, *r] for r in read_models(owner["fits/models"]))
                if "fits/element_model" in owner:
                    elements += ([key, joint, *r] for r in read_element_model(owner["fits/element_model"]))
    archive_joint = archive_joints.split(",")[0].strip()
    rows: list[list[object]] = []
    energies = PREDICTION_COLUMNS[5:9]
    for p in predictions(archive, protocol_text, figures=False):
        head = [p.fit_key, p.predict_key, p.joint or archive_joint]
        if p.element is not None:
            row = prediction_row(p)
            rows.append(
                [
                    *head,
                    "elements",
                    row["element_rmse_nm"],
                    *(row[c] for c in energies),
                    *_ranges(p.element.ranges),
                ]
            )
        rows.append([*head, "bouc_wen", p.rmse_nm, *[math.nan] * len(energies), *_ranges(p.bouc_wen_ranges)])
    return (
        ("models.csv", MODEL_COLUMNS, models),
        ("elements.csv", ELEMENT_COLUMNS, elements),
        ("predictions.csv", PREDICTION_COLUMNS, rows),
    )


def export_tables(archive: Path, output_dir: Path, *, only: KeySelection | None = None) -> tuple[Path, ...]:
    """Write cycles.csv, trials.csv, configurations.csv and the model tables (models.csv, elements.csv,
    predictions.csv) of `archive` into `output_dir`; return them.
    With `only` (`--only`), the rows of those configuration keys alone.

    Raises `InvalidInput` for an unreadable archive, a key of `only` the archive does not hold, or an
    output path that is not a usable directory.
    """
    archive, output_dir = Path(archive), Path(output_dir)
    if output_dir.exists() and not output_dir.is_dir():
        raise InvalidInput(f"Export output {output_dir} is a file; give a directory.")
    data = load_report_data(archive, workers=1)
    if only is not None:
        keys = set(only.select((cfg.key for cfg in data.configurations), archive.name))
        data = dataclasses.replace(
            data, configurations=tuple(c for c in data.configurations if c.key in keys)
        )
    output_dir.mkdir(parents=True, exist_ok=True)
    models = _model_tables(Path(data.session.archive_path), data.protocol_text)
    if only is not None:  # rows of the kept configurations (a prediction: from or to one of them)
        kept = {c.key for c in data.configurations}
        models = tuple(
            (name, columns, [r for r in rows if r[0] in kept or (name == "predictions.csv" and r[1] in kept)])
            for name, columns, rows in models
        )
    for name in ("cycles.csv", "trials.csv", "configurations.csv", *(m[0] for m in models)):
        refuse_special(output_dir / name, "--export")  # all refused before any is written
    with h5py.File(data.session.archive_path, "r") as h5:
        cycles, trials = _rows(h5, data)
    columns, configurations = _configuration_rows(data)
    return (
        _write(output_dir / "cycles.csv", CYCLE_COLUMNS, cycles),
        _write(output_dir / "trials.csv", TRIAL_COLUMNS, trials),
        _write(output_dir / "configurations.csv", columns, configurations),
        *(_write(output_dir / name, columns, rows) for name, columns, rows in models),
    )
