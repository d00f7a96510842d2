"""The report's headline numbers per configuration, on trials as the experimental unit.

One `ConfigurationStats` per configuration and joint (and, with several joints, one of all joints
together, from `total_energy_loss_j`): trials and cycles analysed, energy per cycle as the mean of
trial means with its 95 % t-interval and between-trial CV (`analysis.statistics`), the angle range
reached, and the Bouc-Wen fit quality. `group_repeatability` gives the between-set CV and ICC of a group of
configurations the protocol declares identical (`report.repeatability`, read by `report.differences`).
The report's summary table, the tidy CSV
exports and the session comparison all read these, so they print the same intervals.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from protocol_runner.analysis.statistics import (
    Repeatability,
    TInterval,
    repeatability,
    t_interval,
    trial_means,
)
from protocol_runner.report.model import Configuration, JointsTotal, ReportData


@dataclass(frozen=True)
class TrialEnergy:
    """One trial, the experimental unit: its number and its energy per cycle (the mean over its complete
    cycles with a finite energy, Eq 10-12)."""

    number: int
    energy_j: float


@dataclass(frozen=True)
class ConfigurationStats:
    """Trial-level summary of one configuration; `per_trial` holds the trials with at least one complete
    cycle with a finite energy, in trial order."""

    key: int
    name: str
    set_name: str
    cycles: int
    per_trial: tuple[TrialEnergy, ...]
    energy: TInterval
    angle_min_deg: float
    angle_max_deg: float
    fit_rmse_nm: float
    fit_r2: float
    joint: str = ""  # the joint, or ALL_JOINTS for the energy of all joints together

    @property
    def trials(self) -> int:
        """Trials with at least one complete cycle."""
        return len(self.per_trial)

    @property
    def trial_numbers(self) -> tuple[int, ...]:
        """The numbers of those trials, in order."""
        return tuple(t.number for t in self.per_trial)

    @property
    def trial_energy_j(self) -> tuple[float, ...]:
        """Their energies per cycle, in the same order: the units of the interval and of repeatability."""
        return tuple(t.energy_j for t in self.per_trial)

    @property
    def range_deg(self) -> float:
        """Width of the angle range reached (NaN when nothing was processed)."""
        return self.angle_max_deg - self.angle_min_deg


ALL_JOINTS = "all joints"


def configuration_stats(cfg: Configuration) -> ConfigurationStats:
    """The trial-level statistics of `cfg` (energy per cycle grouped by `energy_cycle_trial`)."""
    fit = cfg.bouc_wen
    return _stats(
        cfg,
        cfg.joint,
        cfg.energy_loss_j,
        cfg.energy_cycle_trial,
        (cfg.angle_min_deg, cfg.angle_max_deg),
        (fit.rmse_nm, fit.r2) if fit is not None else (math.nan, math.nan),
    )


def total_stats(total: JointsTotal, cfg: Configuration) -> ConfigurationStats:
    """The trial-level statistics of the energy of all joints of configuration `cfg` (any joint's part)
    together: no angle range or fit (those are each joint's)."""
    nan2 = (math.nan, math.nan)
    return _stats(cfg, ALL_JOINTS, total.energy_loss_j, total.energy_cycle_trial, nan2, nan2)


def _stats(
    cfg: Configuration,
    joint: str,
    energy_loss_j: np.ndarray,
    cycle_trial: np.ndarray,
    angles: tuple[float, float],
    fit: tuple[float, float],
) -> ConfigurationStats:
    energy = np.asarray(energy_loss_j, dtype=float)
    ids = np.asarray(cycle_trial)
    if ids.size != energy.size:
        ids = np.zeros(energy.size, dtype=np.int64)
    numbers, means = trial_means(energy, ids)
    return ConfigurationStats(
        key=cfg.key,
        name=cfg.name,
        set_name=cfg.set_name,
        cycles=int(np.sum(np.isfinite(energy))),
        per_trial=tuple(TrialEnergy(int(n), float(m)) for n, m in zip(numbers, means, strict=True)),
        energy=t_interval(means),
        angle_min_deg=angles[0],
        angle_max_deg=angles[1],
        fit_rmse_nm=fit[0],
        fit_r2=fit[1],
        joint=joint,
    )


def headline_stats(data: ReportData, key: int) -> tuple[ConfigurationStats, ...]:
    """The statistics of configuration `key`: each joint's, and with several joints all joints' together
    last (when the archive holds that total)."""
    cfgs = data.joint_configurations(key)
    total = data.total(key)
    rows = [configuration_stats(cfg) for cfg in cfgs]
    if data.multi_joint and total is not None and cfgs:
        rows.append(total_stats(total, cfgs[0]))
    return tuple(rows)


def campaign_stats(data: ReportData, key: int) -> ConfigurationStats | None:
    """The statistics a campaign-level number of configuration `key` uses: its one joint's, or with
    several joints all joints' together (None when there is no such total)."""
    rows = headline_stats(data, key)
    if not rows or (data.multi_joint and rows[-1].joint != ALL_JOINTS):
        return None
    return rows[-1] if data.multi_joint else rows[0]


def group_repeatability(data: ReportData, keys: tuple[int, ...]) -> Repeatability:
    """Between-configuration CV and ICC(1) of the trial means of the configurations `keys` (with several
    joints, of all joints together)."""
    units = []
    for key in keys:
        stats = campaign_stats(data, key)
        if stats is not None:
            units.append(stats.trial_energy_j)
    return repeatability(units)
