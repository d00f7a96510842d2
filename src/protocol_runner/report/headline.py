"""The report's headline numbers per configuration, on trials as the experimental unit.

One `ConfigurationStats` per configuration: trials and cycles analysed, energy per cycle as the mean of
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
from protocol_runner.report.model import Configuration, ReportData


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


def configuration_stats(cfg: Configuration) -> ConfigurationStats:
    """The trial-level statistics of `cfg` (energy per cycle grouped by `energy_cycle_trial`)."""
    energy = np.asarray(cfg.energy_loss_j, dtype=float)
    ids = np.asarray(cfg.energy_cycle_trial)
    if ids.size != energy.size:
        ids = np.zeros(energy.size, dtype=np.int64)
    numbers, means = trial_means(energy, ids)
    fit = cfg.bouc_wen
    return ConfigurationStats(
        key=cfg.key,
        name=cfg.name,
        set_name=cfg.set_name,
        cycles=int(np.sum(np.isfinite(energy))),
        per_trial=tuple(TrialEnergy(int(n), float(m)) for n, m in zip(numbers, means, strict=True)),
        energy=t_interval(means),
        angle_min_deg=cfg.angle_min_deg,
        angle_max_deg=cfg.angle_max_deg,
        fit_rmse_nm=fit.rmse_nm if fit is not None else math.nan,
        fit_r2=fit.r2 if fit is not None else math.nan,
    )


def group_repeatability(data: ReportData, keys: tuple[int, ...]) -> Repeatability:
    """Between-configuration CV and ICC(1) of the trial means of the configurations `keys`."""
    units = []
    for key in keys:
        cfg = data.configuration(key)
        if cfg is not None:
            units.append(configuration_stats(cfg).trial_energy_j)
    return repeatability(units)
