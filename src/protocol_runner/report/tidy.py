"""Tidy CSV tables of an archive: one row per cycle, per trial and per configuration, units in the names.

`cycles.csv`: configuration, set, trial, brace, joint, cycle, energy_j, angle_min_deg, angle_max_deg,
torque_peak_nm. The energy is the archived `energy_loss_j` (Eq 10-12); the angle and torque columns come
from the trial's archived processed data cut into the same complete cycles (`analysis.cycles`), and are
left empty when that cut does not give the archived number of cycles (e.g. cycles dropped where the brace
torque was undefined). `brace` is `on-off`: every value is the brace's own torque, brace-on minus
brace-off at equal angles (§3.3).

`trials.csv`: one row per trial with its cycle count, mean and within-trial standard deviation of the
energy per cycle, the angle range and peak torque of its processed data, and how well its brace-off twin
matched it: `brace_off_scaling_error_deg` (the kept run's cycle-range error, docs/analysis.md §3),
`brace_off_scaling_runs` (robot runs the scaling made), `brace_off_scaling_converged` and
`clipped_fraction` (share of brace-on samples beyond the brace-off range, given its nearest torque, §4).

`configurations.csv`: one row per configuration with its settings (profile, trajectory name, then one column
per declared factor holding its level label and one per factor quantity, `<factor>.<quantity>`, the unit in
the quantity's suffix; a list such as a range [lo, hi] is written `lo;hi`), trials, cycles, the mean of
trial means with its 95 % t-interval and between-trial CV (`report.headline`, the numbers of the report's
summary table), the angle reached and the Bouc-Wen fit quality.

`models.csv`, `elements.csv`, `predictions.csv`: the model comparison, the element model's parameters
with their intervals and the declared predictions (`report.model_tables`).

Public API: export_tables(archive, output_dir) -> tuple[Path, ...]
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable, Sequence
from pathlib import Path

import h5py
import numpy as np

from protocol_runner.analysis.cycles import complete_cycles
from protocol_runner.analysis.validation import AnalysisError
from protocol_runner.errors import InvalidInput
from protocol_runner.report.headline import configuration_stats
from protocol_runner.report.load import load_report_data
from protocol_runner.report.model import Configuration, ReportData
from protocol_runner.report.model_tables import export_model_tables

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


def _cell(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return "" if not math.isfinite(value) else repr(value)
    if isinstance(value, tuple | list):
        return ";".join(_cell(v) for v in value)
    return str(value)


def _write(path: Path, columns: Sequence[str], rows: Iterable[Sequence[object]]) -> Path:
    tmp = path.with_name(f".{path.name}.partial")
    with tmp.open("w", encoding="utf-8", newline="") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(columns)
        for row in rows:
            writer.writerow([_cell(v) for v in row])
    tmp.replace(path)
    return path


def _processed(h5: h5py.File, cfg: Configuration, trial: int) -> tuple[np.ndarray, np.ndarray] | None:
    path = f"configurations/{cfg.name}/trials/{trial}/processed"
    if path not in h5:
        return None
    grp = h5[path]
    if "angle_deg" not in grp or "brace_torque_nm" not in grp:
        return None
    angle = np.asarray(grp["angle_deg"][()], dtype=float)
    torque = np.asarray(grp["brace_torque_nm"][()], dtype=float)
    n = min(angle.size, torque.size)
    return angle[:n], torque[:n]


def _brace_off_match(h5: h5py.File, cfg: Configuration, trial: int) -> list[object]:
    """The trial's scaling error (deg) and runs, whether it converged, and its clipped fraction; empty
    cells for what the archive does not hold (an equal-time subtraction, a multi-joint trial)."""
    base = f"configurations/{cfg.name}/trials/{trial}"
    error: float | None = None
    runs: int | None = None
    converged: bool | None = None
    scaling = f"{base}/brace_off/scaling"
    if scaling in h5 and "range_error_deg" in h5[scaling]:
        g = h5[scaling]
        errors = np.asarray(g["range_error_deg"][()], dtype=float)
        kept = int(g.attrs.get("kept_iteration", int(np.argmin(errors)) + 1))
        error, runs = float(errors[kept - 1]), int(errors.size)
        converged = bool(g.attrs.get("converged", False))
    clipped: float | None = None
    if f"{base}/processed" in h5 and "coverage" in h5[f"{base}/processed"].attrs:
        clipped = 1.0 - float(h5[f"{base}/processed"].attrs["coverage"])
    return [error, runs, converged, clipped]


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
        for number in numbers:
            own = energy[ids == number] if ids.size == energy.size else np.empty(0)
            signal = _processed(h5, cfg, number)
            geometry = _cycle_geometry(signal, own.size)
            for i, (e, geo) in enumerate(zip(own, geometry, strict=True), start=1):
                cycles.append(
                    [cfg.key, cfg.set_name, number, "on-off", data.session.joint, i, float(e), *geo]
                )
            lo = hi = peak = math.nan
            if signal is not None and signal[0].size:
                lo, hi = float(np.nanmin(signal[0])), float(np.nanmax(signal[0]))
                peak = float(np.nanmax(np.abs(signal[1])))
            mean = float(own.mean()) if own.size else math.nan
            sd = float(own.std(ddof=1)) if own.size > 1 else math.nan
            match = _brace_off_match(h5, cfg, number)
            trials.append([cfg.key, cfg.set_name, number, int(own.size), mean, sd, lo, hi, peak, *match])
    return cycles, trials


def setting_columns(data: ReportData) -> list[str]:
    """One column per declared factor (its level label) followed by one per factor quantity
    (`<factor>.<quantity>`, the unit in the quantity's suffix), in declaration order, first seen first."""
    names: list[str] = []
    for cfg in data.configurations:
        names.extend(k for k in cfg.settings.flat() if k not in names)
    return names


def _configuration_rows(data: ReportData) -> tuple[list[str], list[list[object]]]:
    setting_names = setting_columns(data)
    columns = ["configuration", "set", "profile", "trajectory", *setting_names, *STAT_COLUMNS]
    rows: list[list[object]] = []
    for cfg in data.configurations:
        s = configuration_stats(cfg)
        flat = cfg.settings.flat()
        rows.append(
            [
                cfg.key,
                cfg.set_name,
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


def export_tables(archive: Path, output_dir: Path) -> tuple[Path, ...]:
    """Write cycles.csv, trials.csv, configurations.csv and the model tables (models.csv, elements.csv,
    predictions.csv: `report.model_tables`) of `archive` into `output_dir`; return them.

    Raises `InvalidInput` for an unreadable archive or an output path that is not a usable directory.
    """
    archive, output_dir = Path(archive), Path(output_dir)
    if output_dir.exists() and not output_dir.is_dir():
        raise InvalidInput(f"Export output {output_dir} is a file; give a directory.")
    data = load_report_data(archive, workers=1)
    output_dir.mkdir(parents=True, exist_ok=True)
    with h5py.File(data.session.archive_path, "r") as h5:
        cycles, trials = _rows(h5, data)
    columns, configurations = _configuration_rows(data)
    return (
        _write(output_dir / "cycles.csv", CYCLE_COLUMNS, cycles),
        _write(output_dir / "trials.csv", TRIAL_COLUMNS, trials),
        _write(output_dir / "configurations.csv", columns, configurations),
        *export_model_tables(Path(data.session.archive_path), data.protocol_text, output_dir),
    )
