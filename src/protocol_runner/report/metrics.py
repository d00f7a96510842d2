"""The metric library of docs/protocol.md "Expectations": one value per trial of a configuration (the
trial is the experimental unit), with `UNITS` and readable `LABELS`.

`range_reached`, `energy_per_degree`, `torque_angle_slope` and `peak_torque` come from every stored sample
of the trial (computed when the archive is read: `range_of`, `slope_of`, `peak_of`). `angle_percentile` and
`hysteresis_width`, which take a parameter, read the copy decimated for plotting (at most a few thousand
samples per trial): close to the whole data's, but every k-th sample only.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from protocol_runner.report.headline import configuration_stats
from protocol_runner.report.model import Configuration, ProcessedTrial

UNITS: dict[str, str] = {
    "energy_per_cycle": "J",
    "energy_per_degree": "J/deg",
    "torque_angle_slope": "N·m/deg",
    "angle_percentile": "deg",
    "range_reached": "deg",
    "peak_torque": "N·m",
    "hysteresis_width": "N·m",
    "fit_rmse": "N·m",
}

LABELS: dict[str, str] = {
    "energy_per_cycle": "energy per cycle",
    "energy_per_degree": "energy per degree of range",
    "torque_angle_slope": "torque-angle slope",
    "angle_percentile": "angle percentile",
    "range_reached": "range reached",
    "peak_torque": "peak torque",
    "hysteresis_width": "hysteresis width",
    "fit_rmse": "fit RMSE",
}

#: Half-width of the angle window of `hysteresis_width` (deg).
HYSTERESIS_WINDOW_DEG = 2.0


def _processed(cfg: Configuration) -> list[ProcessedTrial]:
    return [t.processed for t in cfg.trials if t.processed is not None]


def _finite(angle: np.ndarray, torque: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = min(angle.size, torque.size)
    a, t = np.asarray(angle[:n], dtype=float), np.asarray(torque[:n], dtype=float)
    ok = np.isfinite(a) & np.isfinite(t)
    return a[ok], t[ok]


def range_of(angle_deg: np.ndarray, torque_nm: np.ndarray) -> float:
    a, _ = _finite(angle_deg, torque_nm)
    return float(np.percentile(a, 99) - np.percentile(a, 1)) if a.size else math.nan


def slope_of(angle_deg: np.ndarray, torque_nm: np.ndarray) -> float:
    a, t = _finite(angle_deg, torque_nm)
    if a.size < 3 or np.ptp(a) == 0.0:
        return math.nan
    return float(np.polyfit(a, t, 1)[0])


def peak_of(angle_deg: np.ndarray, torque_nm: np.ndarray) -> float:
    _, t = _finite(angle_deg, torque_nm)
    return float(np.max(np.abs(t))) if t.size else math.nan


def _whole(p: ProcessedTrial, name: str, of: Callable[[np.ndarray, np.ndarray], float]) -> float:
    """`p`'s field `name`, from every sample when the reader computed it, else `of` the plotted copy."""
    value = getattr(p, name)
    return value if math.isfinite(value) else of(p.angle_deg, p.brace_torque_nm)


def _range(p: ProcessedTrial) -> float:
    return _whole(p, "range_deg", range_of)


def _hysteresis(p: ProcessedTrial, angle_deg: float) -> float:
    a, t = _finite(p.angle_deg, p.brace_torque_nm)
    if a.size < 3:
        return math.nan
    direction = np.gradient(a)
    near = np.abs(a - angle_deg) <= HYSTERESIS_WINDOW_DEG
    up, down = near & (direction > 0), near & (direction < 0)
    if not up.any() or not down.any():
        return math.nan
    return float(abs(np.mean(t[up]) - np.mean(t[down])))


def trial_values(
    cfg: Configuration, metric: str, *, percentile: float | None = None, angle_deg: float | None = None
) -> tuple[float, ...]:
    """The metric's finite values for `cfg`, one per trial; empty when the archive lacks the data."""
    values: list[float]
    if metric == "energy_per_cycle":
        values = list(configuration_stats(cfg).trial_energy_j)
    elif metric == "energy_per_degree":
        stats = configuration_stats(cfg)
        ranges = {t.number: _range(t.processed) for t in cfg.trials if t.processed is not None}
        values = [
            e / ranges[n] if ranges.get(n, 0.0) > 0.0 else math.nan
            for n, e in zip(stats.trial_numbers, stats.trial_energy_j, strict=True)
        ]
    elif metric == "fit_rmse":
        fit = cfg.bouc_wen
        values = [] if fit is None else list(fit.cv_rmse_nm) or [fit.rmse_nm]
    else:
        per_trial: dict[str, Callable[[ProcessedTrial], float]] = {
            "torque_angle_slope": lambda p: _whole(p, "slope_nm_per_deg", slope_of),
            "range_reached": _range,
            "peak_torque": lambda p: _whole(p, "peak_nm", peak_of),
            "angle_percentile": lambda p: _percentile(p, percentile),
            "hysteresis_width": lambda p: _hysteresis(p, angle_deg if angle_deg is not None else math.nan),
        }
        if metric not in per_trial:
            raise ValueError(f"unknown metric {metric!r}")
        values = [per_trial[metric](p) for p in _processed(cfg)]
    return tuple(float(v) for v in values if math.isfinite(v))


def _percentile(p: ProcessedTrial, q: float | None) -> float:
    a, _ = _finite(p.angle_deg, p.brace_torque_nm)
    return float(np.percentile(a, q if q is not None else 50.0)) if a.size else math.nan
