"""The report's headline numbers per configuration, on trials as the experimental unit.

One `ConfigurationStats` per configuration and joint (and, with several joints, one of all joints
together, from `total_energy_loss_j`): trials and cycles analysed, energy per cycle as the mean of
trial means with its 95 % t-interval and between-trial CV (`analysis.statistics`), the angle range
reached, and the Bouc-Wen fit quality. The report's summary table, the tidy CSV exports and the session
comparison all read these, so they print the same intervals.

The metric library of docs/protocol.md "Expectations" (`trial_values`): one value per trial of a
configuration, with `UNITS` and readable `LABELS`. `range_reached`, `energy_per_degree`,
`torque_angle_slope` and `peak_torque` come from every stored sample of the trial (computed when the
archive is read: `range_of`, `slope_of`, `peak_of`). `angle_percentile` and `hysteresis_width`, which take
a parameter, read the copy decimated for plotting (every k-th sample, a few thousand per trial).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from protocol_runner.analysis.statistics import TInterval, t_interval, trial_means
from protocol_runner.report.model import Configuration, JointsTotal, ProcessedTrial, ReportData

ALL_JOINTS = "all joints"


@dataclass(frozen=True)
class ConfigurationStats:
    """Trial-level summary of one configuration: the trials with at least one complete cycle with a finite
    energy (`trial_numbers`, in trial order) and their energy per cycle (`trial_energy_j`: the mean over the
    trial's complete cycles with a finite energy, Eq 10-12), the units of the interval and of repeatability."""

    key: int
    set_name: str
    cycles: int
    trial_numbers: tuple[int, ...]
    trial_energy_j: tuple[float, ...]
    energy: TInterval
    angle_min_deg: float
    angle_max_deg: float
    fit_rmse_nm: float
    fit_r2: float
    joint: str = ""  # the joint, or ALL_JOINTS for the energy of all joints together

    @property
    def trials(self) -> int:
        """Trials with at least one complete cycle."""
        return len(self.trial_numbers)


def configuration_stats(cfg: Configuration, total: JointsTotal | None = None) -> ConfigurationStats:
    """The trial-level statistics of `cfg` (energy per cycle grouped by `energy_cycle_trial`); with `total`,
    of the energy of all joints of `cfg`'s configuration together: no angle range or fit (those are each
    joint's)."""
    energy = np.asarray((cfg if total is None else total).energy_loss_j, dtype=float)
    ids = np.asarray((cfg if total is None else total).energy_cycle_trial)
    if ids.size != energy.size:
        ids = np.zeros(energy.size, dtype=np.int64)
    numbers, means = trial_means(energy, ids)
    fit = cfg.bouc_wen if total is None else None
    return ConfigurationStats(
        key=cfg.key,
        set_name=cfg.set_name,
        cycles=int(np.sum(np.isfinite(energy))),
        trial_numbers=tuple(int(n) for n in numbers),
        trial_energy_j=tuple(float(m) for m in means),
        energy=t_interval(means),
        angle_min_deg=cfg.angle_min_deg if total is None else math.nan,
        angle_max_deg=cfg.angle_max_deg if total is None else math.nan,
        fit_rmse_nm=fit.rmse_nm if fit is not None else math.nan,
        fit_r2=fit.r2 if fit is not None else math.nan,
        joint=cfg.joint if total is None else ALL_JOINTS,
    )


def headline_stats(data: ReportData, key: int) -> tuple[ConfigurationStats, ...]:
    """The statistics of configuration `key`: each joint's, and with several joints all joints' together
    last (when the archive holds that total)."""
    cfgs = data.joint_configurations(key)
    total = data.total(key)
    rows = [configuration_stats(cfg) for cfg in cfgs]
    if data.multi_joint and total is not None and cfgs:
        rows.append(configuration_stats(cfgs[0], total))
    return tuple(rows)


def campaign_stats(data: ReportData, key: int) -> ConfigurationStats | None:
    """The statistics a campaign-level number of configuration `key` uses: its one joint's, or with
    several joints all joints' together (None when there is no such total)."""
    rows = headline_stats(data, key)
    if not rows or (data.multi_joint and rows[-1].joint != ALL_JOINTS):
        return None
    return rows[-1] if data.multi_joint else rows[0]


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
        values = [per_trial[metric](t.processed) for t in cfg.trials if t.processed is not None]
    return tuple(float(v) for v in values if math.isfinite(v))


def _percentile(p: ProcessedTrial, q: float | None) -> float:
    a, _ = _finite(p.angle_deg, p.brace_torque_nm)
    return float(np.percentile(a, q if q is not None else 50.0)) if a.size else math.nan
